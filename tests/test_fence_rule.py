"""Which reads are fenced (docs/safety.md): every read on a line that may repeat a reply, only after trouble on a
direct one — shown by the frames on the wire."""

from __future__ import annotations

import pytest

from hil.families.fbs.protocol.fatek import decode_request, split_frame
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.transport.factory import open_transport, serve
from hil.families.fbs.transport.fatek import FatekTransport
from hil.sim.wire_faults import WireFaults


def _sent(transport) -> list[str]:
    codes: list[str] = []
    transport.observers.append(lambda d, f: d == "tx" and codes.append(decode_request(split_frame(bytes(f))).code))
    return codes


@pytest.mark.parametrize("url, fenced", [("emulator+fatek-serial", False), ("emulator+fatek-serial?fence=reads", True),
                                         ("emulator+fatek-tcp", False)])
def test_a_fatek_read_is_fenced_only_where_the_line_may_repeat_a_reply(url, fenced):
    with open_transport(url) as plc:
        plc.read_words("R0", 1)
        sent = _sent(plc)
        assert plc.read_words("R4128", 7)
        assert sent == (["46", "4E"] if fenced else ["46"])
        assert plc.requests_per_read == (2 if fenced else 1)


def test_a_wire_fault_plan_makes_every_read_fenced():
    with open_transport("emulator+fatek-serial", wire_faults=WireFaults()) as plc:
        assert plc.requests_per_read == 2
    with open_transport("emulator+modbus-rtu", wire_faults=WireFaults()) as plc:
        assert plc.requests_per_read == 2
    with open_transport("emulator+modbus-rtu") as plc:
        assert plc.requests_per_read == 1
    with open_transport("emulator+modbus-rtu?fence=reads") as plc:
        assert plc.requests_per_read == 2


def test_on_a_direct_line_a_timeout_is_followed_by_a_resynchronising_loop_back():
    """The reply to the first read is lost; the retry goes out behind a loop-back that drops whatever came late."""
    emulator = Emulator()
    emulator.memory.set("R100", 1234)
    server = serve(emulator, "fatek-serial", faults=WireFaults(script=["drop"]))
    try:
        with FatekTransport(server.address, timeout=0.2, fence="trouble") as plc:
            sent = _sent(plc)
            assert plc.read_words("R100", 1) == [1234]
            assert sent == ["46", "4E", "46"]
            assert plc.resyncs == 1
            sent.clear()
            assert plc.read_words("R100", 1) == [1234]
            assert sent == ["46"]  # in step again: one round trip
    finally:
        server.stop()


def test_fence_must_be_named_rightly():
    from hil.core.errors import TargetError
    with pytest.raises(TargetError, match="fence must be trouble or reads"):
        open_transport("fatek+tcp://127.0.0.1:500?fence=always")
