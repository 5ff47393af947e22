"""open_transport(url): the only way to get a Transport, for every target form in :mod:`hil.io.url`."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, TypedDict, cast

from hil.core.errors import InvalidValue, TargetError
from hil.core.registry import SCHEMES
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.serve_fatek import start_fatek_pty, start_fatek_tcp
from hil.families.fbs.sim.serve_fatek_udp import start_fatek_udp
from hil.families.fbs.sim.serve_modbus import start_modbus_rtu_pty, start_modbus_tcp
from hil.families.fbs.transport.base import Transport
from hil.families.fbs.transport.fatek import FatekOptions, FatekTransport
from hil.families.fbs.transport.local import LocalTransport
from hil.families.fbs.transport.modbus import ModbusTransport
from hil.families.fbs.transport.replay import RecordedPlc, load_recording
from hil.families.fbs.transport.udp import FatekUdpTransport
from hil.io.url import Target, parse_target
from hil.sim.pacing import LineRate
from hil.sim.runtime import ServerHandle

if TYPE_CHECKING:
    from hil.sim.wire_faults import WireFaults

EmulatorFactory = Callable[[], Emulator]
#: the protocols an FBs answers ("local": the in-process emulator)
SPEAKS = ("fatek", "modbus", "local")
#: A pty has no line rate, but pymodbus's RTU client paces itself by the baud rate it is given (inter-frame
#: silences of 3.5 characters): at 9600 that is ≈ 9 ms a round trip of pure waiting (110 round trips/s; 390/s at
#: 115200, and no faster above it).  Only the emulator's own pty client says so; a real line keeps its URL's rate.
PTY_BAUDRATE = 115200


# What each scheme's query may say (hil.families.fbs.wires, hil.io.modbus_schemes): hil.io.url has already
# converted every value with the type its scheme registers, so a query is cast to its scheme's shape, not checked.
class FatekQuery(FatekOptions, total=False):
    """A ``fatek+…``/``replay+fatek`` target's query: the client's settings and the line's fence."""

    fence: str


class ModbusTcpQuery(TypedDict, total=False):
    unit: int
    timeout: float
    retries: int


class SerialQuery(TypedDict, total=False):
    """A serial line's settings (the emulator's pty wires are given their pace in the same keys)."""

    baudrate: int
    bytesize: int
    parity: str
    stopbits: int


class ModbusRtuQuery(ModbusTcpQuery, SerialQuery, total=False):
    fence: str


def open_transport(url: str | Target, *, emulator_factory: EmulatorFactory | None = None,
                   timeout: float | None = None, wire_faults: WireFaults | None = None,
                   line: LineRate | None = None) -> Transport:
    """Open the target named by ``url``.

    For ``emulator…`` targets a fresh in-process emulator is built by ``emulator_factory`` (default: a plain
    FBs main unit) and, for the wire variants, served on loopback or a pty; the returned transport's
    ``.emulator`` is that emulator, ``.server`` its server handle (``.server.faults`` the wire-fault plan given as
    ``wire_faults``, used by the emulator wires only) and closing the transport stops its server;
    ``transport.reopen()`` reconnects the client to the same, still running, server.  ``line``: the pace of the
    emulator's pty wires (a profile's ``[emulator] line``) when the URL gives no ``baudrate`` of its own.
    """
    target = url if isinstance(url, Target) else parse_target(url)
    if target.protocol not in SPEAKS:  # another family's protocol: its own profile reaches it
        raise TargetError(f"target {target} speaks the {target.protocol} protocol, not one of an FBs; an FBs is "
                          f"reached with fatek+tcp://, fatek+udp://, fatek+serial://, fatek+rfc2217://, "
                          f"modbus+tcp://, modbus+rtu:// or modbus+rfc2217:// (or an emulator+fatek-…/"
                          f"emulator+modbus-… target); another PLC "
                          f"needs a profile of its family, e.g. --bench s7-200smart (the bundled S7 emulator) or your "
                          f"copy of example-s7-200smart (hil list shows the bundled profiles)")
    if target.in_process:
        return _open_emulator(target, (emulator_factory or Emulator)(), timeout, wire_faults, line)
    params = dict(target.params)
    if timeout is not None:
        params.setdefault("timeout", timeout)
    if target.scheme == "replay+fatek":
        return _open_replay(target, cast(FatekQuery, params))
    if not SCHEMES[target.scheme].ordered:  # datagrams may come twice or out of order: fence every read
        params.setdefault("fence", "reads")
    if target.scheme == "fatek+udp":
        return FatekUdpTransport(target.host, target.port, description=str(target), **cast(FatekQuery, params))
    if target.protocol == "fatek":
        tcp = target.scheme == "fatek+tcp"
        port_url = f"socket://{target.host}:{target.port}" if tcp else target.serial_port
        # a pty with a baud rate of its own is a paced one (hil emulate --line)
        paced = True if target.scheme == "fatek+serial" and "baudrate" in params else None
        return FatekTransport(port_url, description=str(target), paced=paced,
                              line_name=f"fatek+tcp://{target.host}:{target.port}" if tcp else port_url,
                              **cast(FatekQuery, params))
    if target.scheme == "modbus+tcp":
        return ModbusTransport.tcp(target.host, target.port, **cast(ModbusTcpQuery, params))
    # a device, or an RFC 2217 server's line
    return ModbusTransport.rtu(target.serial_port, **cast(ModbusRtuQuery, params))


def _open_replay(target: Target, params: FatekQuery) -> Transport:
    """A FATEK client talking to a :class:`~hil.families.fbs.transport.replay.RecordedPlc` serving the recording
    on loopback; the transport's ``.replay`` is that peer (``.replay.verify()`` after use), closing the transport
    stops it."""
    peer = RecordedPlc(load_recording(target.device))
    try:
        transport = FatekTransport(f"socket://{peer.address}", description=str(target), **params)
    except BaseException:
        peer.close()
        raise
    transport.replay = peer
    transport.on_close(peer.close)
    return transport


def emulator_line(target: Target, line: LineRate | None = None) -> LineRate | None:
    """The pace of an emulator serial wire: the URL's ``baudrate`` (with its frame, else the protocol's usual one:
    FATEK 7E1, Modbus RTU 8E1), else ``line``; None (unpaced) for every other wire or when neither says."""
    if target.scheme not in ("emulator+fatek-serial", "emulator+modbus-rtu"):
        return None
    params = cast(SerialQuery, target.params)
    if "baudrate" not in params:
        if any(k in params for k in ("bytesize", "parity", "stopbits")):
            raise InvalidValue(f"target {target}: a character frame without a baudrate — give baudrate= too")
        return line
    return LineRate(params["baudrate"], params.get("bytesize", 7 if "fatek" in target.scheme else 8),
                    params.get("parity", "E"), params.get("stopbits", 1))


def _open_emulator(target: Target, emulator: Emulator, timeout: float | None,
                   wire_faults: WireFaults | None = None, line: LineRate | None = None) -> Transport:
    wire = target.scheme.partition("+")[2]
    if not wire:
        return LocalTransport(emulator)
    rate = emulator_line(target, line)
    server = serve(emulator, wire, faults=wire_faults, line=rate)
    # A wire-fault plan can repeat a reply (duplicate, echo) at any time: such a line fences every read.
    fence = "reads" if wire_faults is not None else str(target.params.get("fence", "trouble"))
    try:
        transport = _client_for(wire, server, emulator.station, timeout or 2.0, rate, fence)
    except BaseException:
        server.stop()
        raise
    transport.emulator = emulator
    transport.server = server
    transport.description = f"{target.scheme} ({transport.description})"
    transport.on_close(server.stop)
    return transport


def serve(emulator: Emulator, wire: str, host: str = "127.0.0.1", port: int = 0, *,
          faults: WireFaults | None = None, line: LineRate | None = None) -> ServerHandle:
    """Put ``emulator`` on ``wire`` ("fatek-tcp", "fatek-udp", "fatek-serial", "modbus-tcp", "modbus-rtu");
    ``faults``: a wire-fault plan every reply goes through (the handle keeps it as ``.faults``); ``line``: the pace
    of a pty wire (:mod:`hil.sim.pacing`; the TCP wires have none)."""
    if wire == "fatek-tcp":
        handle = start_fatek_tcp(emulator, host, port, faults=faults)
    elif wire == "fatek-udp":
        handle = start_fatek_udp(emulator, host, port, faults=faults)
    elif wire == "fatek-serial":
        handle = start_fatek_pty(emulator, faults=faults, line=line)
    elif wire == "modbus-tcp":
        handle = start_modbus_tcp(emulator, host, port, unit=emulator.station, faults=faults)
    elif wire == "modbus-rtu":
        handle = start_modbus_rtu_pty(emulator, unit=emulator.station, faults=faults, line=line)
    else:
        raise InvalidValue(f"unknown emulator wire {wire!r}")
    handle.faults = faults
    return handle


def _client_for(wire: str, server: ServerHandle, station: int, timeout: float, line: LineRate | None,
                fence: str) -> Transport:
    settings: SerialQuery = {} if line is None else {"baudrate": line.baudrate, "bytesize": line.bytesize,
                                                     "parity": line.parity, "stopbits": line.stopbits}
    if wire == "fatek-udp":  # every read fenced, whatever the target says (hil.families.fbs.transport.udp)
        host, _, port = server.address.rpartition(":")
        return FatekUdpTransport(host, int(port), station=station, timeout=timeout)
    if wire.startswith("fatek"):
        tcp = wire == "fatek-tcp"
        port_url = f"socket://{server.address}" if tcp else server.address
        return FatekTransport(port_url, station=station, timeout=timeout, fence=fence, paced=line is not None,
                              line_name=f"fatek+tcp://{server.address}" if tcp else None, **settings)
    if wire == "modbus-tcp":
        host, _, port = server.address.rpartition(":")
        return ModbusTransport.tcp(host, int(port), unit=station, timeout=timeout)
    paced: SerialQuery = settings or {"baudrate": PTY_BAUDRATE}
    return ModbusTransport.rtu(server.address, unit=station, timeout=timeout, fence=fence, **paced)
