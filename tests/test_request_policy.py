"""One request policy for every wire (hil.io.request_policy): reads tried 1 + retries times with a doubling pause
and a recovery between tries, writes sent once (a lost one is OutcomeUnknown), refusals final — and the FATEK,
Modbus and S7 wires all keep theirs in it."""

from __future__ import annotations

import pytest

from hil.bench.profile import load_profile
from hil.core.errors import InvalidValue, OutcomeUnknown, PlcErrorReply, ReplyTimeout, TransportError
from hil.families.fbs.transport.factory import open_transport
from hil.families.s7smart.sim.emulator import build_s7_emulator
from hil.families.s7smart.sim.serve_s7 import start_s7_server
from hil.families.s7smart.transport.s7wire import SnapS7Io
from hil.io.request_policy import RequestPolicy, Resync
from tests.test_s7_wire import EPOCH, S7_BENCH


class Lost(Exception):
    pass


def test_the_pause_doubles_from_backoff_up_to_eight_times_it() -> None:
    policy = RequestPolicy(retries=5, backoff=0.05)
    assert [policy.pause(n) for n in range(1, 6)] == [0.05, 0.1, 0.2, 0.4, 0.4]
    assert policy.tries() == 6 and policy.tries(write=True) == 1
    assert policy.pauses(3) == pytest.approx(0.15)
    assert policy.budget(1.0) == pytest.approx(6 + 1.15) and policy.budget(1.0, write=True) == 1.0
    # with a probe of 0.5 s: each read try may be preceded by one, a write by up to 1 + retries
    assert policy.budget(1.0, probe=0.5) == pytest.approx(6 * 1.5 + 1.15)
    assert policy.budget(1.0, write=True, probe=0.5) == pytest.approx(6 * 0.5 + 1.15 + 1.0)
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


def test_the_line_is_resynchronised_before_a_request_and_a_failed_resync_sends_nothing() -> None:
    policy = RequestPolicy(retries=2, backoff=0.0)
    line = {"in step": False, "probes": 0, "sent": 0}

    def probe(n: int, of: int) -> None:
        line["probes"] += 1
        raise Lost(f"no echo to probe {n} of {of}")
    resync = Resync(needed=lambda: not line["in step"], probe=probe, failed=lambda last: f"not sent: {last}")

    def send(n: int, of: int) -> str:
        line["sent"] += 1
        return "value"
    # a write: up to 1 + retries probes, then a ReplyTimeout — nothing was sent, so it is not OutcomeUnknown
    with pytest.raises(ReplyTimeout, match="write R0: not sent: no echo to probe 3 of 3") as info:
        policy.run("write R0", send, write=True, lost=(Lost,), resync=resync)
    assert not isinstance(info.value, OutcomeUnknown) and line == {"in step": False, "probes": 3, "sent": 0}
    # a read: one probe per try (its tries are the retries)
    line["probes"] = 0
    with pytest.raises(ReplyTimeout, match=r"read R0: not sent: no echo to probe 1 of 1; 3 tries of 0.5 s \(1.5 s\)"):
        policy.run("read R0", send, write=False, lost=(Lost,), resync=resync, one_try=0.5)
    assert line["probes"] == 3 and line["sent"] == 0

    def answers(n: int, of: int) -> None:
        line["in step"] = n == 2  # the second probe finds the line in step
        if n < 2:
            raise Lost("stale echo")
    line.update(probes=0)
    resync = Resync(needed=lambda: not line["in step"], probe=answers, failed=str)
    assert policy.run("write R0", send, write=True, lost=(Lost,), resync=resync) == "value" and line["sent"] == 1


def test_the_last_failure_names_what_went_wrong_first_and_decides_the_error() -> None:
    class Stale(Lost):
        pass
    policy = RequestPolicy(retries=1, backoff=0.0)
    failures = iter([Lost("no reply"), Stale("a late reply came first")])

    def flaky(n: int, of: int) -> str:
        raise next(failures)
    with pytest.raises(TransportError, match="read R0: a late reply came first; 2 tries") as info:
        policy.run("read R0", flaky, write=False, lost=(Lost,), timeouts=(ReplyTimeout,))
    assert not isinstance(info.value, ReplyTimeout)  # not a timeout: the reply came, and was not trusted
    state = {"dirty": False}

    def lost_then_unsent(n: int, of: int) -> str:
        state["dirty"] = True
        raise Lost("no reply")

    def probe(n: int, of: int) -> None:
        raise Lost("no echo")
    resync = Resync(needed=lambda: state["dirty"], probe=probe, failed=lambda last: f"not sent ({last})")
    with pytest.raises(ReplyTimeout, match=r"read R0: no reply; then not sent \(no echo\); 2 tries"):
        policy.run("read R0", lost_then_unsent, write=False, lost=(Lost,), resync=resync)


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
