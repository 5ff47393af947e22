"""FATEK over UDP (``fatek+udp://HOST:500?station=1``, ``emulator+fatek-udp``, ``hil emulate --fatek-udp``): a wire
added inside the FBs family package only (hil.families.fbs.wires registers it).  Datagrams may come twice or out
of order, so every read is fenced; the soak (tests/test_soak.py) and the late-reply test (tests/test_late_replies.py)
run over it with reordered ("late"), repeated ("echo", "duplicate") and lost replies in the wire-fault plan."""

from __future__ import annotations

import socket

import pytest

from hil.core.errors import InvalidValue, TargetError
from hil.core.registry import SCHEMES
from hil.families.fbs.address import parse
from hil.families.fbs.protocol.fatek import ReadRegisters, encode_request, split_frame
from hil.families.fbs.transport.factory import open_transport
from hil.io.url import parse_target
from hil.sim.wire_faults import WireFaults
from tests import test_plugin, test_rtc_suites_on_every_target
from tests.conftest import EMULATOR_BENCH
from tests.external import emulate_process

TARGET = "emulator+fatek-udp"


def test_the_url_names_host_port_and_station_and_the_scheme_is_unordered() -> None:
    target = parse_target("fatek+udp://192.0.2.7?station=3&timeout=0.5")
    assert (target.host, target.port, target.params, target.protocol) == ("192.0.2.7", 500,
                                                                          {"station": 3, "timeout": 0.5}, "fatek")
    assert not SCHEMES["fatek+udp"].ordered and SCHEMES["fatek+tcp"].ordered
    with pytest.raises(TargetError, match="unknown parameter 'unit' for fatek\\+udp"):
        parse_target("fatek+udp://192.0.2.7?unit=1")


def test_a_line_that_may_reorder_datagrams_refuses_the_trouble_only_fence() -> None:
    with pytest.raises(InvalidValue, match="fence=trouble relies on replies arriving once and in order"):
        open_transport("fatek+udp://127.0.0.1:9?fence=trouble")


def test_every_read_is_fenced_and_the_values_are_the_emulators() -> None:
    with open_transport(TARGET, timeout=0.5) as plc:
        assert plc.fence_every_read and plc.requests_per_read > 1
        plc.write_words("R1000", [7, 8, 9])
        plc.write_bits("M1000", [1, 0, 1])
        assert plc.read_words("R1000", 3) == [7, 8, 9] and plc.read_bits("M1000", 3) == [1, 0, 1]
        assert plc.emulator.memory.get(parse("R1001")) == 8


@pytest.mark.parametrize("fault", ["late", "echo", "duplicate"])
def test_a_reordered_or_repeated_datagram_is_never_taken_for_the_answer(fault: str) -> None:
    """The reply to one read is withheld and sent before the next one (reordered), or repeated (at once in the
    same datagram, or 1–50 ms later in a datagram of its own); the next read of the same shape still reads its
    own register."""
    faults = WireFaults(delay=0.06)
    with open_transport(TARGET, timeout=0.3, wire_faults=faults) as plc:
        plc.write_words("R1000", [111, 222])
        for _ in range(4):
            faults.push(fault)
            try:
                assert plc.read_words("R1000", 1) == [111]
            except Exception as exc:  # noqa: BLE001 - a withheld reply may time the read out: an error, not a value
                assert fault == "late", exc
            faults.push("delay")
            assert plc.read_words("R1001", 1) == [222]
        assert plc.fenced_out + plc.resyncs > 0
    assert faults.injected[fault] == 4


@pytest.mark.e2e
def test_hil_emulate_serves_it_to_another_program() -> None:
    """``hil emulate --fatek-udp HOST:PORT`` prints ``fatek-udp HOST:PORT``; a FATEK client over UDP reaches it,
    and a request from another socket meanwhile is answered to that socket, the client's next read still right."""
    with emulate_process(EMULATOR_BENCH, 1.0, {"fatek-udp": "--fatek-udp"}) as where:
        host, _, port = where["fatek-udp"].rpartition(":")
        with open_transport(f"fatek+udp://{where['fatek-udp']}?station=1&timeout=1") as plc:
            plc.write_words("R1010", [4321])
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:
                stranger.settimeout(2)
                stranger.sendto(encode_request(1, ReadRegisters(parse("R1010"), 1)), (host, int(port)))
                frame = split_frame(stranger.recv(512))
            assert (frame.station, frame.command, frame.data) == (1, "46", "010E1")  # no error; 4321 = 10E1H
            assert plc.read_words("R1010", 1) == [4321]


def test_the_smoke_suite_passes_over_udp(pytester) -> None:
    test_plugin.test_smoke_suite_passes_on_every_emulator_target(pytester, TARGET)


def test_the_rtc_suites_pass_over_udp(pytester) -> None:
    test_rtc_suites_on_every_target.test_rtc_suites_pass(pytester, TARGET)
