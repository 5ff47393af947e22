"""Registries: what families and wires bring, found by name (as labgrid's ``target_factory`` finds its drivers).

The generic layers (core, io, sim, bench, plugin) name no family, wire or register: they iterate these tables.  A
family's plug-in module fills them when it is imported, and the first look-up imports every installed family (the
``hil.families`` entry points, :mod:`hil.bench.family`), so a new family or wire is its own package plus one entry
point — docs/architecture.md lists what each registers.

=====================  ==========================================================================================
:data:`SCHEMES`        target URL schemes: their protocol, query parameters, default port, what the path names
:data:`PROTOCOLS`      what a wire speaks: the query parameter naming the PLC, its serial scheme, its lab default
:data:`WIRES`          the emulator's wires (``hil emulate --NAME``, ``emulator+NAME``): TCP or pty, the character
                       frame of a paced pty
:data:`REPORT_AREAS`   suite file or folder → report area
:data:`REPORT_PLOTS`   ``report.attach_NAME(…)``: a plot of a family's data
=====================  ==========================================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Generic, TypeVar

#: the entry-point group families register under (``[project.entry-points."hil.families"]``)
GROUP = "hil.families"
#: the light modules that fill these tables, one per family (``[project.entry-points."hil.registers"]``)
REGISTERS = "hil.registers"
T = TypeVar("T")
_loading = {"started": False}


def load_plugins() -> None:
    """Import what every installed family registers, once: its ``hil.registers`` module (a family's plug-in module
    imports it too, so an install that predates that group loads the plug-ins instead).  Marked before loading: a
    module's own look-ups while it is imported see what is registered so far, not a second load."""
    if _loading["started"]:
        return
    _loading["started"] = True
    found = entry_points(group=REGISTERS) or entry_points(group=GROUP)
    for entry in sorted(found, key=lambda e: e.name):
        entry.load()


class Registry(Generic[T]):
    """Named entries, in registration order.  Registering a name twice is allowed only with an equal entry (two
    families that speak one wire both register it); anything else is a bug in a plug-in, refused at import."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._items: dict[str, T] = {}

    def register(self, name: str, item: T) -> T:
        known = self._items.get(name)
        if known is not None and known != item:
            raise ValueError(f"{self.what} {name!r} is registered twice, differently ({known!r}, {item!r})")
        self._items[name] = item
        return item

    def _all(self) -> dict[str, T]:
        load_plugins()
        return self._items

    def __getitem__(self, name: str) -> T:
        return self._all()[name]

    def get(self, name: str) -> T | None:
        return self._all().get(name)

    def __contains__(self, name: object) -> bool:
        return name in self._all()

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._all()))

    def items(self) -> list[tuple[str, T]]:
        return list(self._all().items())

    def values(self) -> list[T]:
        return list(self._all().values())


# -- the wire's side ------------------------------------------------------------------------------------------------
#: query parameters every client scheme takes, a serial line's, and the fence's (hil.io.url.FENCES)
COMMON: Mapping[str, type] = {"timeout": float, "retries": int}
SERIAL: Mapping[str, type] = {"baudrate": int, "parity": str, "bytesize": int, "stopbits": int}
FENCE: Mapping[str, type] = {"fence": str}


@dataclass(frozen=True)
class Scheme:
    """A target URL scheme (``fatek+tcp``, ``emulator+modbus-rtu`` …)."""

    name: str
    #: what it speaks (a :data:`PROTOCOLS` name; "local" for the in-process emulator without a wire)
    protocol: str
    params: Mapping[str, type] = field(default_factory=dict)
    #: HOST:PORT (a network endpoint, an RFC 2217 server's too) rather than a path
    network: bool = False
    #: the port a URL naming none gets (None: the URL must name one — an RFC 2217 server has no standard port)
    default_port: int | None = None
    #: an ``emulator…`` target: the emulator runs in this process (virtual time)
    in_process: bool = False
    #: what the path names, for the error when it is missing ("serial device", "recording")
    path_names: str = "serial device"
    #: what a request fence may rely on: the line delivers each reply once and in order (a serial line, a TCP
    #: stream); False for datagrams (UDP), which may be reordered or repeated — a protocol without transaction
    #: ids then fences every read (docs/safety.md)
    ordered: bool = True
    #: the lanes of one run may use it at once (:mod:`hil.plugin.lanes`): a connection each (TCP, UDP), or a serial
    #: line taken in turn by whole exchanges (:mod:`hil.io.shared_line`); not a server of one client (RFC 2217)
    lanes: bool = False
    #: one URL of this form, for help texts and errors
    example: str = ""


@dataclass(frozen=True)
class Protocol:
    """What a wire speaks (``fatek``, ``modbus``, ``s7``)."""

    name: str
    #: the query parameter naming the PLC on the wire ("station", "unit"); None: it has none (rack and slot)
    address_param: str | None = None
    #: the scheme of its serial line (a device), for messages naming a line a transport opened; None: no serial form
    serial_scheme: str | None = None
    #: the protocol a lab's wire speaks when neither the profile nor the wire's port says (one protocol may be)
    lab_default: bool = False


@dataclass(frozen=True)
class Wire:
    """An emulator wire (``hil emulate --NAME``, target ``emulator+NAME``)."""

    name: str
    protocol: str
    #: "pty" (a pseudo-terminal), else the transport of its HOST:PORT endpoint ("tcp", "udp")
    kind: str
    #: the ``hil emulate`` flag's help
    help: str
    #: a paced pty's usual character frame (its data bits; even parity, one stop bit)
    bytesize: int = 8
    #: earlier spellings of its ``hil emulate`` flag, still accepted (not shown in the help)
    aliases: tuple[str, ...] = ()

    @property
    def option(self) -> str:
        """Its ``hil emulate`` flag: the wire's one name."""
        return f"--{self.name}"


SCHEMES: Registry[Scheme] = Registry("target scheme")
PROTOCOLS: Registry[Protocol] = Registry("protocol")
WIRES: Registry[Wire] = Registry("emulator wire")
#: suite file stem prefix, or a folder on its path → report area ("test_rtc_drift" → "drift"); first match wins
REPORT_AREAS: Registry[str] = Registry("report area")
#: ``report.attach_<name>(…)``: a plot drawn from a family's data, as ``plot(report, …)`` calling
#: ``report.attach_series`` (hil.plugin.reporting.plugin.ReportHandle)
REPORT_PLOTS: Registry[Callable[..., Any]] = Registry("report plot")


def register_scheme(scheme: Scheme) -> Scheme:
    return SCHEMES.register(scheme.name, scheme)


def register_wire(wire: Wire, params: Mapping[str, type] = {}) -> Wire:
    """An emulator wire and its target ``emulator+NAME`` (``params``: what that target's query may say)."""
    register_scheme(Scheme(f"emulator+{wire.name}", wire.protocol, params, in_process=True))
    return WIRES.register(wire.name, wire)


def default_port(scheme: str) -> int | None:
    entry = SCHEMES.get(scheme)
    return entry.default_port if entry is not None else None


def examples() -> str:
    """An emulator wire's target and a PLC's URL, the first registered, for help texts and errors."""
    wire = next((f"emulator+{name}" for name in WIRES), "emulator")
    plc = next((s.example for s in SCHEMES.values() if s.network and s.default_port and s.example), "")
    return f"{wire}, {plc}" if plc else wire


def lab_protocol() -> str:
    """The protocol a lab's wire speaks when nothing says (the one registered as the lab default)."""
    return next(p.name for p in PROTOCOLS.values() if p.lab_default)


__all__ = ["COMMON", "FENCE", "GROUP", "PROTOCOLS", "REPORT_AREAS", "REPORT_PLOTS", "Registry", "SCHEMES", "SERIAL",
           "Scheme",
           "Protocol", "WIRES", "Wire", "default_port", "examples", "lab_protocol", "load_plugins",
           "register_scheme", "register_wire"]
