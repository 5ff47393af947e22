"""What the S7-200 SMART family registers for its wires (:mod:`hil.core.registry`): the S7 protocol
(ISO-on-TCP, port 102) and its emulator wire, and Modbus (the CPU's V memory on Modbus, :mod:`.protocol.modbus_map`)."""

from __future__ import annotations

from hil.core.registry import COMMON, PROTOCOLS, REPORT_AREAS, Protocol, Scheme, Wire, register_scheme, register_wire
from hil.io.modbus_schemes import register_modbus

PROTOCOLS.register("s7", Protocol("s7"))  # the CPU is named by rack and slot, and has no serial form
register_scheme(Scheme("s7+tcp", "s7", {**COMMON, "rack": int, "slot": int}, network=True, default_port=102,
                       lanes=True, example="s7+tcp://HOST:102?rack=0&slot=1"))
register_wire(Wire("s7-tcp", "s7", "tcp", "the S7 protocol (ISO-on-TCP; an S7-200 SMART profile, e.g. "
                   "fixtures/benches/s7-200smart.toml; port 0: OS chooses)"))
register_modbus()

# its suites' report area (a folder of its own, and its files' prefix)
REPORT_AREAS.register("s7smart", "S7")
REPORT_AREAS.register("test_s7", "S7")
