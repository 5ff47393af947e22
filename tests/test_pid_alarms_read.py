"""``pid.alarms``: every box's WR+0 … WR+3 and ALM in one planned read, the same values the per-box reads give, on
the emulator over a real FATEK/TCP wire (loopback, a port the OS chose)."""

from __future__ import annotations

import pytest

from hil.bench.profile import load_profile
from hil.families.fbs.bench import Bench
from tests.conftest import EMULATOR_BENCH


@pytest.fixture
def bench():
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator+fatek-tcp")
    yield bench
    bench.close()


def test_alarms_read_every_box_in_one_round_trip_and_agree_with_the_per_box_reads(bench) -> None:
    pid, raw = bench.plc.pid, bench.raw
    boxes = list(pid.config.instances)
    # distinct words in every box, so that a mixed-up box or word shows (written past the guard: FUN86's outputs
    # are not the suites' to write; every EN is off, so FUN86 leaves WR be)
    for n, inst in enumerate(boxes):
        raw.write_words(str(inst.wr), [0x1111 * (n + 1) + i for i in range(4)])
    before = bench.raw.requests
    alarms = pid.alarms(boxes)
    assert bench.raw.requests - before == 1, "every box's WR+0…3 and ALM fit one FATEK frame"
    for inst in boxes:
        assert alarms[inst.name].words == pid.alarm_words(inst).words, inst.name
        assert alarms[inst.name].alm is pid.alm(inst), inst.name
        assert alarms[inst.name].sn == inst.sn
    assert len({alarms[i.name].words for i in boxes}) == len(boxes)
