"""A set is proved from the PLC's side: ``hil rtc set`` reads the clock back and exits non-zero when a PLC that
reports the set as taken (M1955 = 0) does not show the time sent.  The PLC is ``hil emulate`` in another process,
once correct and once with the set dropped, reached only over FATEK/TCP and Modbus/TCP."""

from __future__ import annotations

import subprocess
import sys

import pytest

from hil.families.fbs.sim.models.rtc import RtcModel
from tests.broken import BrokenEmulator, replace_model
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import hil_emulate


class DropsTheSet(RtcModel):
    """M1952 falls, M1955 stays 0, and the chip keeps its old time."""

    def on_hold_edge(self, emu):
        emu.memory.bits["M"][1955] = 0


def with_rtc(cls):
    def breakage(emulator, profile, epoch):
        rtc = profile.rtc
        replace_model(emulator, RtcModel, cls(chip=rtc.chip, crystal_ppm=rtc.crystal_ppm, start=rtc.start or epoch))
    return BrokenEmulator(breakage)


def hil_rtc_set(url: str, when: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hil.cli.main", "rtc", "set", url, when], capture_output=True,
                          text=True, cwd=REPO, timeout=60)


@pytest.mark.parametrize("broken, lost", [
    (None, None),
    ("tests.test_rtc_set_proof:with_rtc:DropsTheSet", "the set was lost"),
    # date and time loaded, the weekday cleared to 0: a Friday (5) reads back as Sunday
    ("tests.test_rtc_suites_catch_broken_plcs:with_rtc:SetClearsTheWeekday", "the weekday sent (5) was lost"),
], ids=["correct", "drops", "clears-weekday"])
@pytest.mark.e2e
def test_hil_rtc_set_reads_back(tmp_path, broken, lost):
    profile = tmp_path / "bench.toml"
    profile.write_text(EMULATOR_BENCH.read_text())
    with hil_emulate(profile, 1.0, modbus=True, broken=broken) as where:
        for url in (f"fatek+tcp://{where['fatek-tcp']}", f"modbus+tcp://{where['modbus-tcp']}?unit=1"):
            done = hil_rtc_set(url, "2031-07-04 12:00:00")
            if broken is None:
                assert done.returncode == 0, done.stdout + done.stderr
                assert "accepted" in done.stdout
            else:
                assert done.returncode != 0, done.stdout + done.stderr
                assert lost in done.stdout + done.stderr, done.stdout + done.stderr
                assert "Traceback" not in done.stderr
