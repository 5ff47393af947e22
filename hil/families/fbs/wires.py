"""What the FBs family registers for its wires (:mod:`hil.core.registry`): the FATEK protocol, its URL schemes
(TCP and UDP on port 500, a serial line, an RFC 2217 server's line, a recorded trace), its emulator wires, and Modbus
(the FBs memory on the Modbus map, :mod:`hil.families.fbs.protocol.modbus_map`)."""

from __future__ import annotations

from hil.core.registry import COMMON, FENCE, PROTOCOLS, SERIAL, Protocol, Scheme, Wire, register_scheme, register_wire
from hil.io.modbus_schemes import register_modbus

#: the FBs's own protocol; a lab's wire that says nothing else speaks it
PROTOCOLS.register("fatek", Protocol("fatek", address_param="station", serial_scheme="fatek+serial", lab_default=True))
register_wire(Wire("fatek-tcp", "fatek", "tcp", "FATEK protocol on TCP (port 0: OS chooses)"))
register_wire(Wire("fatek-udp", "fatek", "udp", "FATEK protocol on UDP, as FBs Ethernet modules answer it (port 0: "
                   "OS chooses)"))
register_wire(Wire("fatek-serial", "fatek", "pty", "FATEK protocol on a pseudo-terminal", bytesize=7,
                   aliases=("fatek-pty",)), {**SERIAL, **FENCE})
register_scheme(Scheme("fatek+tcp", "fatek", {**COMMON, **FENCE, "station": int}, network=True, default_port=500,
                       lanes=True, example="fatek+tcp://HOST:500"))
# datagrams may come twice or out of order: every read is fenced (hil.families.fbs.transport.udp)
register_scheme(Scheme("fatek+udp", "fatek", {**COMMON, **FENCE, "station": int}, network=True, default_port=500,
                       ordered=False, lanes=True, example="fatek+udp://HOST:500?station=1"))
register_scheme(Scheme("fatek+serial", "fatek", {**COMMON, **SERIAL, **FENCE, "station": int},
                       lanes=True, example="fatek+serial:///dev/ttyUSB0?baudrate=9600"))
register_scheme(Scheme("fatek+rfc2217", "fatek", {**COMMON, **SERIAL, **FENCE, "station": int}, network=True,
                       example="fatek+rfc2217://HOST:PORT?station=1"))
register_scheme(Scheme("replay+fatek", "fatek", {**COMMON, "station": int}, path_names="recording",
                       example="replay+fatek:///path/to/trace.txt"))
register_modbus()
