"""Target URLs: one string picks the PLC and the wire.  Every scheme is registered by the family or wire that speaks
it (:data:`hil.core.registry.SCHEMES`: its parameters, default port, protocol); the bundled ones:

    emulator                                  in-process emulator, no wire
    emulator+fatek-tcp | emulator+fatek-serial | emulator+modbus-tcp | emulator+modbus-rtu
                                              in-process emulator served on loopback / a pty, reached over that wire
    emulator+fatek-serial?baudrate=9600&parity=E&bytesize=7
                                              the pty paced at that line rate (hil.sim.pacing; 7E1 for FATEK,
                                              8E1 for Modbus RTU unless given)
    fatek+tcp://host:500?station=1&timeout=1&retries=2
    fatek+serial:///dev/ttyUSB0?baudrate=9600&parity=E&bytesize=7&stopbits=1&station=1
    modbus+tcp://host:502?unit=1&timeout=1&retries=2
    modbus+rtu:///dev/ttyUSB0?baudrate=9600&parity=E&unit=1
    fatek+rfc2217://host:port?station=1&baudrate=9600&parity=E&bytesize=7&stopbits=1
    modbus+rfc2217://host:port?unit=1&baudrate=9600&parity=E
                                              a serial line exported by an RFC 2217 server (ser2net, a labgrid
                                              exporter), its line settings sent over the protocol (hil.io.line)
    s7+tcp://host:102?rack=0&slot=1           an S7-200 SMART over its own protocol (ISO-on-TCP)
    emulator+s7-tcp                           the in-process S7 emulator served over that protocol
    replay+fatek:///path/to/trace.txt?station=1  a recorded FATEK wire trace, answered frame by frame
                                              (hil.families.fbs.transport.replay)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, urlsplit

from hil.core.errors import TargetError
from hil.core.registry import PROTOCOLS, SCHEMES, Scheme, register_scheme
from hil.io.line import is_rfc2217

#: fence=reads: the line may repeat a reply (a gateway, a protocol converter): every read is fenced; fence=trouble
#: (the default): a direct line, fenced only after a timeout, a retry or a stray frame (docs/safety.md)
FENCES = ("trouble", "reads")
#: the in-process emulator without a wire; every other scheme is a family's or a wire's (hil.core.registry)
register_scheme(Scheme("emulator", "local", in_process=True))


def forms() -> str:
    """The registered target forms, for the error naming an unknown scheme."""
    return ", ".join(s.example or s.name for s in SCHEMES.values())


def emulator_targets() -> tuple[str, ...]:
    return tuple(name for name, s in SCHEMES.items() if s.in_process)


@dataclass(frozen=True)
class Target:
    scheme: str  # "emulator", "emulator+fatek-tcp", "fatek+tcp", …
    host: str = ""
    port: int = 0
    device: str = ""
    params: dict[str, object] = field(default_factory=dict)

    @property
    def in_process(self) -> bool:
        """True for the ``emulator…`` targets: the emulator runs inside this process (virtual time)."""
        return SCHEMES[self.scheme].in_process

    @property
    def protocol(self) -> str:
        """What the scheme speaks (a registered protocol's name), "local" for the emulator without a wire."""
        return SCHEMES[self.scheme].protocol

    @property
    def serial_port(self) -> str:
        """The pyserial URL of a serial target's line: its device, or ``rfc2217://HOST:PORT`` for a line exported
        by an RFC 2217 server ("" for a TCP target)."""
        if is_rfc2217_scheme(self.scheme):
            host = f"[{self.host}]" if ":" in self.host else self.host
            return f"rfc2217://{host}:{self.port}"
        return self.device

    def __str__(self) -> str:
        if self.in_process:
            return self.scheme + ("?" + "&".join(f"{k}={v}" for k, v in self.params.items()) if self.params else "")
        where = f"{self.host}:{self.port}" if self.host else self.device
        query = "&".join(f"{k}={v}" for k, v in self.params.items())
        return f"{self.scheme}://{where}" + (f"?{query}" if query else "")


def is_rfc2217_scheme(scheme: str) -> bool:
    """A serial line exported by an RFC 2217 server (``<protocol>+rfc2217``): HOST:PORT, a serial line's settings."""
    return scheme.endswith("+rfc2217")


def serial_target(protocol: str, port: str) -> str:
    """The target URL of ``protocol`` on the serial ``port`` a transport opens (a device, or an RFC 2217 server's
    ``rfc2217://HOST:PORT``), for messages and reports."""
    if is_rfc2217(port):
        return f"{protocol}+{port}"
    return f"{PROTOCOLS[protocol].serial_scheme}://{port}"


def parse_target(url: str) -> Target:
    text = url.strip()
    in_process = emulator_targets()
    if text in in_process:
        return Target(text)
    scheme, mark, query = text.partition("?")
    if mark and scheme in in_process:
        return Target(scheme, params=_params(url, scheme, query))
    if text.startswith("emulator"):
        raise TargetError(f"unknown emulator target {url!r} — use one of: {', '.join(in_process)}")
    try:
        parts = urlsplit(text)
    except ValueError as exc:  # "Invalid IPv6 URL": an unclosed [
        raise TargetError(f"cannot use target {url!r}: {exc} (an IPv6 host goes in brackets, e.g. "
                          f"{text.partition('://')[0]}://[::1]:PORT)") from None
    scheme = parts.scheme
    if scheme not in SCHEMES or SCHEMES[scheme].in_process:
        raise TargetError(f"cannot use target {url!r}: unknown scheme {scheme!r} — write one of "
                          f"these forms: {forms()}")
    entry = SCHEMES[scheme]
    params = _params(url, scheme, parts.query)
    if entry.network:
        example_port = entry.default_port or 3001
        if not parts.hostname:
            raise TargetError(f"target {url!r} names no host — give one, e.g. {scheme}://192.168.1.3:{example_port}")
        try:
            port = parts.port or entry.default_port or 0
        except ValueError:
            raise TargetError(f"target {url!r} has an invalid port — give 1–65535") from None
        if not port:
            raise TargetError(f"target {url!r} names no port: an RFC 2217 server has no standard one — give the "
                              f"port of its telnet(rfc2217) accepter (e.g. {scheme}://{parts.hostname}:{example_port})")
        return Target(scheme, host=parts.hostname, port=port, params=params)
    device = (parts.netloc + parts.path) if parts.netloc else parts.path
    if not device:
        raise TargetError(f"target {url!r} names no {entry.path_names} (e.g. {entry.example or scheme + '://PATH'})")
    return Target(scheme, device=device, params=params)


def _params(url: str, scheme: str, query: str) -> dict[str, object]:
    allowed = SCHEMES[scheme].params
    out: dict[str, object] = {}
    for key, raw in parse_qsl(query, keep_blank_values=True):
        if key not in allowed:
            raise TargetError(f"target {url!r}: unknown parameter {key!r} for {scheme} "
                              f"(known: {', '.join(sorted(allowed))})")
        try:
            value = allowed[key](raw)
        except ValueError:
            raise TargetError(f"target {url!r}: {key}={raw!r} is not a valid {allowed[key].__name__}") from None
        if key == "fence" and value not in FENCES:
            raise TargetError(f"target {url!r}: fence must be {' or '.join(FENCES)}, not {raw!r}")
        if key == "parity":
            value = str(value).upper()
            if value not in ("N", "E", "O"):
                raise TargetError(f"target {url!r}: parity must be N, E or O, not {raw!r}")
        out[key] = value
    return out
