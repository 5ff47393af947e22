"""One request policy for every wire (hil.io.request_policy): reads tried 1 + retries times with a doubling pause
and a recovery between tries, writes sent once (a lost one is OutcomeUnknown), refusals final — and the FATEK,
Modbus and S7 wires all keep theirs in it."""

from __future__ import annotations

import pytest

from hil.core.errors import InvalidValue, OutcomeUnknown, PlcErrorReply, ReplyTimeout
from hil.families.fbs.transport.factory import open_transport
from hil.families.s7smart.sim.emulator import build_s7_emulator
from hil.families.s7smart.transport.s7wire import SnapS7Io
from hil.families.s7smart.sim.serve_s7 import start_s7_server
from hil.bench.profile import load_profile
from hil.io.request_policy import RequestPolicy
from tests.test_s7_wire import EPOCH, S7_BENCH


class Lost(Exception):
    pass


def test_the_pause_doubles_from_backoff_up_to_eight_times_it() -> None:
    policy = RequestPolicy(retries=5, backoff=0.05)
    assert [policy.pause(n) for n in range(1, 6)] == [0.05, 0.1, 0.2, 0.4, 0.4]
    assert policy.tries() == 6 and policy.tries(write=True) == 1
    assert policy.pauses(3) == pytest.approx(0.15)
    assert policy.budget(1.0) == pytest.approx(6 + 1.15) and policy.budget(1.0, write=True) == 1.0
    with pytest.raises(InvalidValue, match="retries must be 0 or more"):
        RequestPolicy(retries=-1)


def test_a_read_is_tried_again_after_recovering_and_a_write_never_is() -> None:
    policy = RequestPolicy(retries=2, backoff=0.0)
    tries: list[tuple[int, int]] = []
    recovered: list[int] = []

    def flaky(n: int, of: int) -> str:
        tries.append((n, of))
        if n < 3:
            raise Lost(f"no reply to try {n}")
        return "value"
    assert policy.run("read R0", flaky, write=False, lost=(Lost,), recover=lambda: recovered.append(1)) == "value"
    assert tries == [(1, 3), (2, 3), (3, 3)] and len(recovered) == 2

    tries.clear()
    with pytest.raises(OutcomeUnknown, match="write R0: no reply to try 1 — the write may or may not have been"):
        policy.run("write R0", flaky, write=True, lost=(Lost,))
    assert tries == [(1, 1)]

    def silent(n: int, of: int) -> str:
        raise Lost(f"silence {n}")
    with pytest.raises(ReplyTimeout, match=r"read R0: silence 3; 3 tries, .* s in all"):
        policy.run("read R0", silent, write=False, lost=(Lost,))


def test_a_refusal_is_final() -> None:
    calls = []

    def refused(n: int, of: int) -> str:
        calls.append(n)
        raise PlcErrorReply("A", "no such address")
    with pytest.raises(PlcErrorReply):
        RequestPolicy(retries=2).run("read R9999", refused, write=False, lost=(Lost,))
    assert calls == [1]


@pytest.mark.parametrize("target", ["emulator+fatek-tcp", "emulator+fatek-udp", "emulator+modbus-tcp"])
def test_the_fbs_wires_pause_by_the_policy(target: str) -> None:
    with open_transport(target, timeout=0.5) as plc:
        inner = getattr(plc, "wire", plc)
        assert isinstance(inner.policy, RequestPolicy) and inner.policy.retries == inner.retries


def test_the_s7_wire_keeps_its_retries_in_the_policy() -> None:
    server = start_s7_server(build_s7_emulator(load_profile(S7_BENCH), EPOCH))
    try:
        host, _, port = server.address.rpartition(":")
        with SnapS7Io(host, int(port), timeout=0.5, retries=3) as io:
            assert io.policy == RequestPolicy(retries=3)
            assert len(io.read_v(100, 2)) == 2
    finally:
        server.stop()
