"""``[bench] answers_at_scan_end``: where the profile says the port services each request at a scan's end (port 0's
rule), a settle relies on that rule — round trips, each a scan — instead of proving each scan with the ladder's
scan counter; without it, the counter proves every settle."""

from __future__ import annotations

import dataclasses

import pytest

from hil.bench.profile import load_profile
from hil.families.fbs.bench import Bench
from tests.conftest import EMULATOR_BENCH


def _frames(declared: bool, read_between: bool = False) -> list[str]:
    profile = dataclasses.replace(load_profile(EMULATOR_BENCH), answers_at_scan_end=declared)
    assert profile.scan_counter == "R3999"
    bench = Bench(profile, target="emulator+fatek-tcp")
    sent: list[str] = []
    bench.raw.observers.append(lambda direction, frame: sent.append(frame.decode()) if direction == "tx" else None)
    try:
        bench.begin_test("settles")
        bench.plc.io.status()  # (the identity, asked once, out of the way)
        bench.plc.io.write("M1953", 0)
        before = len(sent)
        if read_between:
            bench.plc.io.read("R4128")
        bench.plc.settle()
        bench.plc.settle_before_request()
        bench.plc.read_settled(["M1955"])
        settling = sent[before:]
        bench.end_test()
        return settling
    finally:
        bench.close()


def _commands(frames: list[str]) -> list[str]:
    return [f[3:5] for f in frames]


def test_the_scan_counter_proves_every_settle_unless_the_port_keeps_port_0s_rule():
    proved, trusted = _frames(False), _frames(True)
    counter_reads = [f for f in proved if "R03999" in f]
    assert len(counter_reads) >= 6, proved  # two for each: settle, settle_before_request, read_settled
    assert not any("R03999" in f for f in trusted), trusted
    # port 0's rule, counted from the write: settle_scans (2) round trips for the settle — status requests —, and
    # then none before the next request nor before the settled read, which are scans after the write already
    assert _commands(trusted) == ["40", "40", "44"], trusted
    assert len(trusted) < len(proved)


def test_reads_since_the_write_count_as_its_settles_round_trips_on_port_0():
    """A read answered after the write spans a scan as a status request does: the settle sends one status fewer.
    A write starts the count again."""
    assert _commands(_frames(True, read_between=True)) == ["46", "40", "44"]


def test_answers_at_scan_end_is_read_from_the_profile_and_must_be_a_boolean(tmp_path):
    text = EMULATOR_BENCH.read_text()
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[bench]\n", "[bench]\nanswers_at_scan_end = true\n", 1))
    assert load_profile(good).answers_at_scan_end is True
    assert load_profile(EMULATOR_BENCH).answers_at_scan_end is False
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[bench]\n", '[bench]\nanswers_at_scan_end = "yes"\n', 1))
    with pytest.raises(Exception, match="answers_at_scan_end must be a bool"):
        load_profile(bad)
