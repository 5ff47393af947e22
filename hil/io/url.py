"""Target URLs: one string picks the PLC and the wire.

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
    replay+fatek:///path/to/trace.txt?station=1  a recorded FATEK wire trace, answered frame by frame (hil.families.fbs.transport.replay)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, urlsplit

from hil.core.errors import TargetError
from hil.io.line import is_rfc2217

EMULATOR_WIRES = ("fatek-tcp", "fatek-serial", "modbus-tcp", "modbus-rtu", "s7-tcp")
EMULATOR_TARGETS = ("emulator",) + tuple(f"emulator+{w}" for w in EMULATOR_WIRES)

_COMMON = {"timeout": float, "retries": int}
_SERIAL = {"baudrate": int, "parity": str, "bytesize": int, "stopbits": int}
#: fence=reads: the line may repeat a reply (a gateway, a protocol converter): every read is fenced; fence=trouble
#: (the default): a direct line, fenced only after a timeout, a retry or a stray frame (README, Safety)
_FENCE = {"fence": str}
FENCES = ("trouble", "reads")
PARAMS: dict[str, dict[str, type]] = {
    "fatek+tcp": {**_COMMON, **_FENCE, "station": int},
    "fatek+serial": {**_COMMON, **_SERIAL, **_FENCE, "station": int},
    "modbus+tcp": {**_COMMON, "unit": int},
    "modbus+rtu": {**_COMMON, **_SERIAL, **_FENCE, "unit": int},
    "fatek+rfc2217": {**_COMMON, **_SERIAL, **_FENCE, "station": int},
    "modbus+rfc2217": {**_COMMON, **_SERIAL, **_FENCE, "unit": int},
    "replay+fatek": {**_COMMON, "station": int},
    # the emulator's serial wires: the pty's line rate (the client opens it with the same settings)
    "emulator+fatek-serial": {**_SERIAL, **_FENCE},
    "emulator+modbus-rtu": {**_SERIAL, **_FENCE},
    "s7+tcp": {**_COMMON, "rack": int, "slot": int},
}
from hil.core.ports import DEFAULT_PORTS, NETWORK_SCHEMES  # noqa: E402 - also used to key bench locks (hil.core.lock)

FORMS = ("emulator, emulator+fatek-tcp, emulator+fatek-serial, emulator+modbus-tcp, emulator+modbus-rtu, "
         "fatek+tcp://HOST:500, fatek+serial:///dev/ttyUSB0?baudrate=9600, modbus+tcp://HOST:502?unit=1, "
         "modbus+rtu:///dev/ttyUSB0?baudrate=9600&parity=E&unit=1, fatek+rfc2217://HOST:PORT?station=1, "
         "modbus+rfc2217://HOST:PORT?unit=1, s7+tcp://HOST:102?rack=0&slot=1, "
         "emulator+s7-tcp, replay+fatek:///path/to/trace.txt")


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
        return self.scheme in EMULATOR_TARGETS

    @property
    def protocol(self) -> str:
        """"fatek", "modbus", "s7" or "local"."""
        if self.scheme == "emulator":
            return "local"
        for protocol in ("modbus", "s7"):
            if protocol in self.scheme:
                return protocol
        return "fatek"

    @property
    def serial_port(self) -> str:
        """The pyserial URL of a serial target's line: its device, or ``rfc2217://HOST:PORT`` for a line exported
        by an RFC 2217 server ("" for a TCP target)."""
        if self.scheme.endswith("rfc2217"):
            host = f"[{self.host}]" if ":" in self.host else self.host
            return f"rfc2217://{host}:{self.port}"
        return self.device

    def __str__(self) -> str:
        if self.in_process:
            return self.scheme + ("?" + "&".join(f"{k}={v}" for k, v in self.params.items()) if self.params else "")
        where = f"{self.host}:{self.port}" if self.host else self.device
        query = "&".join(f"{k}={v}" for k, v in self.params.items())
        return f"{self.scheme}://{where}" + (f"?{query}" if query else "")


def serial_target(protocol: str, port: str) -> str:
    """The target URL of ``protocol`` ("fatek", "modbus") on the serial ``port`` a transport opens (a device, or an
    RFC 2217 server's ``rfc2217://HOST:PORT``), for messages and reports."""
    if is_rfc2217(port):
        return f"{protocol}+{port}"
    return f"{protocol}+{'rtu' if protocol == 'modbus' else 'serial'}://{port}"


def parse_target(url: str) -> Target:
    text = url.strip()
    if text in EMULATOR_TARGETS:
        return Target(text)
    scheme, mark, query = text.partition("?")
    if mark and scheme in PARAMS and scheme in EMULATOR_TARGETS:
        return Target(scheme, params=_params(url, scheme, query))
    if text.startswith("emulator"):
        raise TargetError(f"unknown emulator target {url!r}; use one of: {', '.join(EMULATOR_TARGETS)}")
    try:
        parts = urlsplit(text)
    except ValueError as exc:  # "Invalid IPv6 URL": an unclosed [
        raise TargetError(f"cannot use target {url!r}: {exc} (an IPv6 host goes in brackets, e.g. "
                          f"fatek+tcp://[::1]:500)") from None
    scheme = parts.scheme
    if scheme not in PARAMS:
        raise TargetError(f"cannot use target {url!r}: unknown scheme {scheme!r}. Targets look like: {FORMS}")
    params = _params(url, scheme, parts.query)
    if scheme.endswith(NETWORK_SCHEMES):
        example_port = DEFAULT_PORTS.get(scheme, 3001)
        if not parts.hostname:
            raise TargetError(f"target {url!r} names no host (e.g. {scheme}://192.168.1.3:{example_port})")
        try:
            port = parts.port or DEFAULT_PORTS.get(scheme, 0)
        except ValueError:
            raise TargetError(f"target {url!r} has an invalid port") from None
        if not port:
            raise TargetError(f"target {url!r} names no port: an RFC 2217 server has no standard one — give the "
                              f"port of its telnet(rfc2217) accepter (e.g. {scheme}://{parts.hostname}:{example_port})")
        return Target(scheme, host=parts.hostname, port=port, params=params)
    device = (parts.netloc + parts.path) if parts.netloc else parts.path
    if not device:
        example = "/path/to/trace.txt" if scheme.startswith("replay") else "/dev/ttyUSB0"
        raise TargetError(f"target {url!r} names no {'recording' if scheme.startswith('replay') else 'serial device'} "
                          f"(e.g. {scheme}://{example})")
    return Target(scheme, device=device, params=params)


def _params(url: str, scheme: str, query: str) -> dict[str, object]:
    allowed = PARAMS[scheme]
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
