"""A PLC's memory has a fixed size: when a model's scan changes the length of a memory bank — a slice assignment of
the wrong length inserts or drops elements, and every later register moves — the engine fails loudly, naming the
model and the bank.  Without it the emulator's Python list just grows, a request reads other registers than it
names, and a suite may pass on them (issue 39: the RTC read-out inserted before R4128 passed every RTC suite)."""

from __future__ import annotations

import datetime as dt
import re
import threading

import pytest

from hil.bench.profile import load_profile
from hil.core.errors import EmulatorFault
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.rtc import RtcModel
from hil.families.fbs.sim.plc import Emulator
from hil.families.s7smart.sim.cpu import S7Emulator
from hil.sim.model import Model
from tests.broken import BrokenEmulator, inline_suites, replace_model
from tests.conftest import EMULATOR_BENCH

EPOCH = dt.datetime(2024, 2, 28, 23, 0, 0)
RTC_SUITES = ["test_rtc.py", "test_rtc_validity.py", "test_rtc_adjust.py", "test_rtc_drift.py"]


class ReadOutInserted(RtcModel):
    """Inserts the read-out before R4128 instead of writing it over R4128–R4134 (``words[4128:4128 % 7] = …``):
    R4128–R4134 still read the time, every later register has moved up by 7."""

    def copy_out(self, emu, t):
        words = emu.memory.words["R"]
        words[4128:4128 % 7] = t.to_registers()
        words[4135] = t.hour_minute_word()


class Grows(Model):
    """Appends an element to a bank at every scan once ``trigger`` (a bank, an index) is set."""

    name = "grows"

    def __init__(self, bank: str, trigger: tuple[str, int]) -> None:
        self.bank, self.trigger = bank, trigger

    def scan(self, emu) -> None:
        kind, index = self.trigger
        banks = emu.memory.banks()
        if banks[kind][index]:
            banks[self.bank].append(0)


def broken_rtc(emulator: Emulator, profile: object, epoch: object) -> None:
    rtc = next(m for m in emulator.models if type(m) is RtcModel)
    replace_model(emulator, RtcModel, ReadOutInserted(chip=rtc.chip, crystal_ppm=rtc.crystal_ppm, start=EPOCH))


def test_a_model_that_resizes_a_bank_fails_the_scan_naming_both():
    emulator = build_emulator(load_profile(EMULATOR_BENCH), EPOCH)
    broken_rtc(emulator, None, None)
    said = r"'rtc' \(ReadOutInserted\).* model changed the size of memory: R from 8072 to \d+ elements"
    with pytest.raises(EmulatorFault, match=said):
        emulator.service(lambda mem: mem.read("R4128", 8))  # a request comes with a scan: it fails, loudly
    with pytest.raises(EmulatorFault):  # and so does every scan after it: no request reads the moved registers
        emulator.service(lambda mem: mem.read("R4136", 1))


def test_a_correct_emulator_keeps_every_bank_through_a_day():
    emulator = build_emulator(load_profile(EMULATOR_BENCH), EPOCH)
    sizes = {name: len(bank) for name, bank in emulator.memory.banks().items()}
    emulator.advance(86400)
    assert {name: len(bank) for name, bank in emulator.memory.banks().items()} == sizes


def test_the_rtc_suites_fail_on_a_read_out_that_moves_the_registers(pytester, capfd):
    """The bench's first request fails: the run stops, saying why, before any test passes."""
    run = inline_suites(pytester, RTC_SUITES, BrokenEmulator(broken_rtc))
    passed, _skipped, _failed = run.listoutcomes()
    assert run.ret != pytest.ExitCode.OK and passed == []
    said = r"'rtc' \(ReadOutInserted\).* model changed the size of memory: R from 8072"
    assert re.search(said, capfd.readouterr().err)


def test_real_time_answers_the_waiting_request_with_the_fault():
    """``hil emulate``'s clock: the scan fails in the real-time loop, which stops; the request that waited for that
    scan gets the fault (a server answers it as an error) instead of waiting for ever."""
    emulator = Emulator(models=[Grows("D", ("M", 1000))])
    stop, raised = threading.Event(), []

    def clock() -> None:
        try:
            emulator.run_realtime(stop)
        except EmulatorFault as exc:
            raised.append(exc)
    thread = threading.Thread(target=clock, daemon=True)
    thread.start()
    try:
        emulator.service(lambda mem: mem.set("M1000", 1))
        said = r"the 'grows' \(Grows\) model changed the size of memory: D from 4096 to"
        with pytest.raises(EmulatorFault, match=said):
            emulator.service(lambda mem: mem.read("D0", 1))
    finally:
        stop.set()
        thread.join(5)
    assert not thread.is_alive() and raised, "the real-time loop went on after a failed scan"


def test_an_s7_area_has_a_fixed_size_too():
    emulator = S7Emulator(models=[Grows("V", ("SM", 0))])
    emulator.service(lambda mem: mem.set("SMB0", 1))  # (the scan before the write is still whole)
    with pytest.raises(EmulatorFault, match=r"V from 20480 to 20481 elements"):
        emulator.service(lambda mem: mem.read_bytes("V", 0, 1))
