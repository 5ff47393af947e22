"""The CLI with an S7-200 SMART bench: ``hil probe`` shows the CPU read-only; FBs-only commands refuse clearly."""

from __future__ import annotations

import pytest

from hil.cli.main import main
from tests.conftest import REPO

S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"


@pytest.mark.parametrize("target", [None, "emulator"])
def test_probe_shows_an_s7_cpu_and_its_clock_buffers(capsys, target):
    argv = ["probe", "--bench", str(S7_BENCH)] + ([target] if target else [])
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "S7-200 SMART" in out
    assert "READ_RTC buffer VB130" in out and "SET_RTC buffer VB110" in out and "trigger V100.0" in out
    assert "Traceback" not in out


@pytest.mark.parametrize("argv", [["rtc", "read", "emulator"], ["rtc", "sync", "emulator"],
                                  ["drift", "measure", "emulator", "--duration", "60"]],
                         ids=["rtc-read", "rtc-sync", "drift-measure"])
def test_fbs_clock_commands_refuse_an_s7_bench_and_say_what_to_run(capsys, argv):
    assert main(argv[:2] + ["--bench", str(S7_BENCH)] + argv[2:]) == 4
    err = capsys.readouterr().err
    assert "is an S7-200 SMART" in err and f"hil run --bench {S7_BENCH}" in err
