"""A place's resources → the run's target URL, every resolvable resource's URL, and the fault rig's coils.

=====================  ==============================================================================================
``NetworkService``     the PLC's Ethernet module: ``fatek+tcp://ADDRESS:PORT?station=N`` (``modbus+tcp://…?unit=N``
                       on port 502 or ``[labgrid] protocol = "modbus"``; ``s7+tcp://`` on port 102)
``NetworkSerialPort``  a serial port an exporter serves through ser2net (what it publishes for a ``RawSerialPort`` or
                       ``USBSerialPort``): ``fatek+rfc2217://HOST:PORT?baudrate=SPEED&station=N`` (or
                       ``modbus+rfc2217://…?unit=N``); the port is ser2net's, new on every acquire
``ModbusTCPCoil``      one relay of the fault rig: every ``[faults.*] kind = "modbus-coil"`` that names no ``target``
                       gets ``modbus+tcp://HOST?unit=1``, and the coils the place holds become its allow-list
=====================  ==============================================================================================
"""

from __future__ import annotations

import copy
import datetime as dt
import fnmatch
from dataclasses import dataclass, field
from typing import Any

from hil.bench.lab.client import LabError, Place, Resource
from hil.bench.lab.spec import LabSpec
from hil.core.errors import ProfileError
from hil.core.lock import lock_key
from hil.core.registry import PROTOCOLS, SCHEMES, lab_protocol

WIRES = ("NetworkService", "NetworkSerialPort")
RIG = "ModbusTCPCoil"
PENDING_HOST = "labgrid.invalid"  # RFC 2606: never resolves — a profile checked before its place is reserved


@dataclass(frozen=True)
class Lab:
    """What the run got from labgrid: where, from whom, and the URLs its place resolved to."""

    coordinator: str
    place: str
    asked: str  # what the run reserved by: "place NAME" or "tags k=v …"
    target: str  # the wire's URL
    wire: str = ""  # the wire resource's path, exporter/group/class/name
    tags: dict[str, str] = field(default_factory=dict)
    token: str = ""
    acquired_by: str = ""
    exporters: tuple[str, ...] = ()
    exporter_hosts: tuple[str, ...] = ()
    urls: tuple[tuple[str, str], ...] = ()  # every wire-like resource: its name → URL (or why not)
    rig: str | None = None  # the relay module's URL
    rig_coils: frozenset[int] | None = None  # the coils the place holds (None: not known yet)
    waited: float = 0.0
    acquired_at: str = ""

    @classmethod
    def pending(cls, spec: LabSpec) -> Lab:
        """Stand-in URLs to check a profile before its place is reserved (nothing may connect to them)."""
        protocol = spec.protocol or lab_protocol()
        return cls(spec.address, spec.place or "", spec.describe(), f"{protocol}+tcp://{PENDING_HOST}",
                   rig=f"modbus+tcp://{PENDING_HOST}?unit=1")

    @property
    def lock_target(self) -> str:
        """The key of hil's local bench lock for this place (a second guard beside labgrid's own exclusion)."""
        return f"labgrid://{lock_key('labgrid+tcp://' + self.coordinator).removeprefix('tcp://')}/{self.place}"

    def apply(self, data: dict[str, Any], where: str = "<profile>") -> dict[str, Any]:
        """The profile's tables with the place's URLs filled in: ``[bench] target`` and the target and allow-list
        of every ``modbus-coil`` fault that names no target of its own; ``[labgrid]`` taken out."""
        data = copy.deepcopy(data)
        data.pop("labgrid", None)
        data.setdefault("bench", {})["target"] = self.target
        for name, table in data.get("faults", {}).items():
            if not isinstance(table, dict) or table.get("kind") != "modbus-coil" or "target" in table:
                continue
            if self.rig is None:
                raise ProfileError(f"{where}: [faults.{name}] takes its relay module from the place's ModbusTCPCoil "
                                   f"resources, and labgrid place {self.place} has none (matching "
                                   f"[labgrid] rig) — add them to the place, or give the fault a target")
            if "coils" in table:
                raise ProfileError(f"{where}: [faults.{name}] coils: the coils a labgrid place holds are the "
                                   f"rig's allow-list — remove the key")
            table["target"] = self.rig
            if self.rig_coils is not None:
                table["coils"] = ranges(self.rig_coils)
        return data

    def properties(self) -> list[tuple[str, str]]:
        """For the JUnit testsuite properties and the HTML header (hil.plugin.reporting.identity)."""
        props = [("hil.lab.coordinator", self.coordinator), ("hil.lab.place", self.place),
                 ("hil.lab.tags", " ".join(f"{k}={v}" for k, v in sorted(self.tags.items())) or "none"),
                 ("hil.lab.reserved_by", self.asked), ("hil.lab.reservation", self.token),
                 ("hil.lab.acquired_by", self.acquired_by), ("hil.lab.acquired_at", self.acquired_at),
                 ("hil.lab.waited_s", f"{self.waited:.1f}"),
                 ("hil.lab.exporter", ", ".join(self.exporters)),
                 ("hil.lab.exporter_host", ", ".join(self.exporter_hosts)),
                 ("hil.lab.wire", f"{self.wire} → {self.target}")]
        props += [(f"hil.lab.url.{name}", url) for name, url in self.urls]
        if self.rig is not None:
            coils = ranges(self.rig_coils) if self.rig_coils is not None else "?"
            props.append(("hil.lab.rig", f"{self.rig} coils {coils}"))
        return props


def resolve(spec: LabSpec, place: Place, *, token: str = "", station: int = 1, waited: float = 0.0) -> Lab:
    """The :class:`Lab` for an acquired ``place``: refuses, naming the resources, what it cannot use."""
    wire = _wire(spec, place)
    urls = []
    for resource in place.resources:
        if resource.cls in WIRES:
            try:
                urls.append((resource.name, url_of(resource, spec, station)))
            except LabError as exc:
                urls.append((resource.name, f"unusable: {exc}"))
    rig, coils = _rig(spec, place)
    used = [wire, *(r for r in place.resources if r.cls == RIG)]
    return Lab(spec.address, place.name, spec.asked,
               url_of(wire, spec, station), wire=wire.path, tags=dict(place.tags), token=token,
               acquired_by=place.acquired or "", exporters=tuple(sorted({r.exporter for r in used})),
               exporter_hosts=tuple(sorted({r.exporter_host for r in used})), urls=tuple(urls), rig=rig,
               rig_coils=coils, waited=waited, acquired_at=dt.datetime.now().astimezone().isoformat(timespec="seconds"))


def url_of(resource: Resource, spec: LabSpec, station: int) -> str:
    """The target URL that reaches the PLC through ``resource``."""
    p = resource.params
    if resource.isolated:
        raise LabError(f"{resource.path}: its exporter is isolated (reached only through an SSH proxy); hil connects "
                       f"to resources directly — export it without --isolated")
    if resource.cls == "NetworkService":
        port = int(p.get("port", 0))
        protocol = spec.protocol or next((s.protocol for s in SCHEMES.values()
                                          if s.network and s.default_port == port), lab_protocol())
        scheme, where = f"{protocol}+tcp", _host(str(p.get("address", "")), port)
    elif resource.cls == "NetworkSerialPort":
        if p.get("protocol", "rfc2217") != "rfc2217":
            raise LabError(f"{resource.path} speaks {p.get('protocol')!r}, not RFC 2217: export it through ser2net "
                           f"as RFC 2217 (a RawSerialPort or USBSerialPort does that)")
        if not p.get("port"):
            raise LabError(f"{resource.path} has no port yet: its exporter starts ser2net when the place is acquired")
        protocol = spec.protocol or lab_protocol()
        if PROTOCOLS[protocol].serial_scheme is None:
            raise LabError(f"{resource.path}: a serial port cannot carry the {protocol} protocol")
        scheme, where = f"{protocol}+rfc2217", _host(str(p.get("host", "")), int(p["port"]))
    else:
        raise LabError(f"{resource.path} is a {resource.cls}, not a PLC wire ({' or '.join(WIRES)})")
    query: dict[str, Any] = {}
    if resource.cls == "NetworkSerialPort":
        query["baudrate"] = int(p.get("speed", 9600))
    address = PROTOCOLS[protocol].address_param
    if address is not None:
        query[address] = station
    query.update(dict(spec.params))
    text = "&".join(f"{k}={v}" for k, v in query.items())
    return f"{scheme}://{where}" + (f"?{text}" if text else "")


def _host(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _wire(spec: LabSpec, place: Place) -> Resource:
    if spec.wire:
        for resource in place.resources:
            if resource.name == spec.wire:
                return resource
        raise LabError(f"labgrid place {place.name} has no resource named {spec.wire!r} ([labgrid] wire); it has: "
                       f"{_names(place.resources)}")
    for cls in WIRES:
        found = [r for r in place.resources if r.cls == cls]
        if len(found) == 1:
            return found[0]
        if found:
            raise LabError(f"labgrid place {place.name} has {len(found)} {cls} resources ({_names(found)}): name the "
                           f"PLC's wire with [labgrid] wire")
    raise LabError(f"labgrid place {place.name} has no PLC wire (a NetworkService or a NetworkSerialPort); it has: "
                   f"{_names(place.resources)}")


def _rig(spec: LabSpec, place: Place) -> tuple[str | None, frozenset[int] | None]:
    coils = [r for r in place.resources if r.cls == RIG and fnmatch.fnmatchcase(r.name, spec.rig)]
    if not coils:
        return None, None
    hosts = sorted({str(r.params.get("host")) for r in coils})
    if len(hosts) > 1:
        raise LabError(f"labgrid place {place.name}: the rig's ModbusTCPCoil resources are on {len(hosts)} hosts "
                       f"({', '.join(hosts)}); hil drives one relay module — narrow [labgrid] rig to one of them")
    inverted = [r.name for r in coils if r.params.get("invert")]
    if inverted:
        raise LabError(f"labgrid place {place.name}: {', '.join(inverted)} are inverted (active-low); hil's rig "
                       f"opens a circuit with coil = 1 — wire the relays active-high")
    return f"modbus+tcp://{hosts[0]}?unit=1", frozenset(int(r.params["coil"]) for r in coils)


def ranges(numbers: frozenset[int]) -> str:
    """{0, 1, 2, 5} → "0-2, 5" (the form of ``[faults] coils``)."""
    out: list[str] = []
    for n in sorted(numbers):
        if out and out[-1].rpartition("-")[2] == str(n - 1):
            out[-1] = f"{out[-1].partition('-')[0]}-{n}"
        else:
            out.append(str(n))
    return ", ".join(out)


def _names(resources: Any) -> str:
    return ", ".join(f"{r.name} ({r.cls})" for r in resources) or "no resources"


__all__ = ["Lab", "resolve", "url_of", "ranges", "PENDING_HOST"]
