"""A late or repeated reply is never taken for the answer to a later request (issue 15): a copy of one read's reply
that lands while the next read of the same shape waits for its own is skipped by transaction id on Modbus/TCP and
caught by the fence after every read on FATEK (a 4E loop-back) and Modbus RTU (a probe read), and the read is
repeated.  The soak (tests/test_soak.py) does the same at random; this one lands the copy on purpose."""

from __future__ import annotations

import pytest
from pymodbus.server import ModbusTcpServer

from hil.core.errors import TransportError
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.serve_modbus import build_device
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.modbus import ModbusTransport
from hil.sim.runtime import LoopThread
from hil.sim.wire_faults import WireFaults

WIRES = ["emulator+fatek-tcp", "emulator+fatek-udp", "emulator+fatek-serial", "emulator+modbus-tcp",
         "emulator+modbus-rtu"]
ROUNDS = 6


@pytest.mark.parametrize("wire", WIRES)
def test_a_repeated_reply_landing_before_the_answer_is_never_taken_for_it(wire):
    # The first read's reply is repeated 1–50 ms later; the second read's reply is held 60 ms, so the copy lands
    # first, while the second read waits — a client that takes the first frame of the right shape reads 111.
    faults = WireFaults(delay=0.06)
    with open_transport(wire, timeout=0.5, wire_faults=faults) as plc:
        plc.write_words("R1000", [111, 222])
        frames: list[tuple[str, bytes]] = []
        plc.observers.append(lambda direction, frame: frames.append((direction, bytes(frame))))
        landed = 0
        for _ in range(ROUNDS):
            frames.clear()
            faults.push("echo")
            assert plc.read_words("R1000", 1) == [111]
            original = next(frame for direction, frame in frames if direction == "rx")
            mark = len(frames)
            faults.push("delay")
            assert plc.read_words("R1001", 1) == [222]
            landed += any(direction == "rx" and original in frame for direction, frame in frames[mark:])
    assert faults.injected["echo"] == faults.injected["delay"] == ROUNDS
    assert landed >= ROUNDS // 2, f"the copy landed in the second read's wait in only {landed} of {ROUNDS} rounds"


def test_a_modbus_tcp_reply_with_transaction_id_0_is_refused():
    """pymodbus's sync client skips a reply whose transaction id is another non-zero one (the test above) and
    refuses one with id 0 — a server that does not echo ids — rather than trust a reply it cannot match (its
    framer alone would let id 0 through).  hil.io.modbus_client relies on both."""
    runtime = LoopThread.shared()

    def zero_tid(sending: bool, data: bytes) -> bytes:
        return b"\x00\x00" + data[2:] if sending else data

    async def start() -> ModbusTcpServer:
        server = ModbusTcpServer(build_device(Emulator(), 1), address=("127.0.0.1", 0), trace_packet=zero_tid)
        await server.serve_forever(background=True)
        return server

    server = runtime.run(start())
    port = server.transport.sockets[0].getsockname()[1]
    try:
        with (
            ModbusTransport.tcp("127.0.0.1", port, unit=1, timeout=0.3, retries=0) as plc,
            pytest.raises(TransportError, match="transaction id=1 but received 0"),
        ):
            plc.read_words("R0", 1)
    finally:
        runtime.run(server.shutdown())
