"""``hil rtc`` and ``hil drift``: in-process through hil.cli.main.main, plus one run of the installed console script."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.cli.main import main

HIL = Path(sys.executable).parent / "hil"
EMULATOR_BENCH = Path(__file__).resolve().parent.parent / "fixtures" / "benches" / "emulator.toml"
MODBUS_MAP = "the default FBs Modbus map"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hil: error: "), err
    assert "Traceback" not in err


# -- drift code / decode ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("rate, code, steps", [("3.38", "56E5H", "+39"), ("-5.62", "5603H", "-64"),
                                               ("\u22125.62", "5603H", "-64")])
def test_drift_code_manual_examples(capsys, rate, code, steps):
    rc, out, _ = run(capsys, "drift", "code", rate)
    assert rc == 0
    assert out.splitlines()[0] == code
    assert f"fine, {steps} steps" in out and "s/day" in out and "ppm" in out


@pytest.mark.parametrize("text", ["56E5", "56E5H", "0x56E5", "56e5h"])
def test_drift_decode_forms(capsys, text):
    rc, out, _ = run(capsys, "drift", "decode", text)
    assert rc == 0
    assert "56E5H" in out
    assert re.search(r"mode\s+│ fine", out)
    assert "+39" in out
    assert "+3.4277 s/day" in out and "+39.673" in out


def test_drift_decode_no_correction(capsys):
    rc, out, _ = run(capsys, "drift", "decode", "0000H")
    assert rc == 0 and "no correction" in out


@pytest.mark.parametrize("argv, says", [
    (["drift", "decode", "zz"], "56E5, 56E5H or 0x56E5"),
    (["drift", "decode", "1234"], "high byte must be 56H"),
    (["drift", "decode", "0x156E5"], "56E5, 56E5H or 0x56E5"),
    (["drift", "code", "fast"], "s/day as a number"),
    (["drift", "code", "20"], "outside the S-35390A setting range"),
])
def test_drift_bad_input(capsys, argv, says):
    rc, out, err = run(capsys, *argv)
    assert rc == 4
    assert out == ""
    assert_one_line_error(err)
    assert says in err


def test_console_script_bad_code_is_one_line():
    # timeout: a hang guard (a busy host may take seconds to start Python and import hil)
    done = subprocess.run([str(HIL), "drift", "decode", "G00D"], capture_output=True, text=True, timeout=90,
                          env={"COLUMNS": "40", "PATH": "/usr/bin:/bin"})
    assert done.returncode == 4
    assert done.stdout == ""
    assert_one_line_error(done.stderr)
    assert "'G00D'" in done.stderr and "0x56E5" in done.stderr


# -- rtc read / set / sync ----------------------------------------------------------------------------------------
WEEKDAY = r"(Sunday|Monday|Tuesday|Wednesday|Thursday|Friday|Saturday)"


@pytest.mark.parametrize("url", ["emulator", "emulator+fatek-tcp"])
def test_rtc_read(capsys, url):
    rc, out, _ = run(capsys, "rtc", "read", url)
    assert rc == 0
    assert re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d " + WEEKDAY, out)
    assert "S-35390A (3)" in out
    assert re.search(r"M1954 installed\s+│ 1", out) and re.search(r"M1955 set error\s+│ 0", out)
    assert re.search(r"R4135 hour/minute\s+│ [0-9A-F]{4}H", out)
    assert "0000H: no correction" in out
    assert "in step" in out


def test_rtc_read_modbus_cannot_reach_d4053(capsys):
    rc, out, _ = run(capsys, "rtc", "read", "emulator+modbus-tcp")
    assert rc == 0
    assert re.search(r"chip D4053\s+│ not reachable over " + MODBUS_MAP, out)
    assert re.search(r"rate code D4054\s+│ not reachable over", out)
    assert re.search(WEEKDAY, out) and "in step" in out


@pytest.mark.parametrize("url", ["emulator", "emulator+fatek-tcp"])
@pytest.mark.parametrize("when", ["2024-02-29 12:00:00", "2024-02-29T12:00"])
def test_rtc_set_accepted(capsys, url, when):
    rc, out, _ = run(capsys, "rtc", "set", url, when)
    assert rc == 0
    assert "accepted" in out and "M1955 = 0" in out
    assert "PLC now shows 2024-02-29 12:00:0" in out and "Thursday" in out


def test_rtc_set_over_modbus(capsys):
    rc, out, _ = run(capsys, "rtc", "set", "emulator+modbus-tcp", "2030-01-01 00:00:00")
    assert rc == 0 and "2030-01-01 00:00:00 Tuesday" in out


@pytest.mark.parametrize("url", ["emulator", "emulator+fatek-tcp"])
def test_rtc_set_refused(capsys, url):
    rc, out, _ = run(capsys, "rtc", "set", url, "2023-02-29 00:00:00")
    assert rc == 1
    assert "refused" in out and "M1955 = 1" in out
    assert "day=29" in out


@pytest.mark.parametrize("when, says", [("tomorrow", "YYYY-MM-DD HH:MM:SS"), ("1999-12-31 23:59:59", "2000–2099")])
def test_rtc_set_bad_time(capsys, when, says):
    rc, _, err = run(capsys, "rtc", "set", "emulator", when)
    assert rc == 4
    assert_one_line_error(err)
    assert says in err


@pytest.mark.parametrize("url", ["emulator", "emulator+fatek-tcp"])
def test_rtc_sync(capsys, url):
    rc, out, _ = run(capsys, "rtc", "sync", url)
    assert rc == 0
    assert "accepted" in out and "host time" in out


# -- drift measure ------------------------------------------------------------------------------------------------
def bench_with_crystal(tmp_path: Path, ppm: float) -> Path:
    text = re.sub(r"(?m)^crystal_ppm\s*=.*$", f"crystal_ppm = {ppm}", EMULATOR_BENCH.read_text())
    path = tmp_path / "bench.toml"
    path.write_text(text)
    return path


def test_drift_measure_of_an_emulator_day_runs_on_virtual_time(capsys, monkeypatch):
    """A day of bench time passes on the emulator's clock, not the host's: the host is asked to sleep none of it
    (counted, not timed; the day's wall time is a benchmark's figure: benchmarks/bench_host_time.py)."""
    slept: list[float] = []
    sleep = time.sleep
    monkeypatch.setattr(time, "sleep", lambda seconds: (slept.append(seconds), sleep(seconds))[1])
    rc, out, _ = run(capsys, "drift", "measure", "emulator", "--duration", "86400")
    assert rc == 0
    assert re.search(r"measured over\s+│ 864\d\d\.\d s bench time", out)  # a whole day of bench time…
    assert sum(slept) < 1.0, f"…but the host slept {sum(slept):.1f} s of it"  # …none of it slept on the host
    assert re.search(r"drift\s+│ [+-]\d+\.\d{3} s/day", out)
    assert re.search(r"ppm\s+│ [+-]\d+\.\d{3}", out) and "resolution" in out
    assert re.search(r"compensating code\s+│ [0-9A-F]{4}H", out)
    assert "━" not in out  # no progress bar on the emulator / off a terminal


def test_drift_measure_finds_the_manuals_code(capsys, tmp_path):
    bench = bench_with_crystal(tmp_path, -65.05)  # ≈ −5.62 s/day
    rc, out, _ = run(capsys, "drift", "measure", "emulator+fatek-tcp", "--duration", "86400", "--bench", str(bench))
    assert rc == 0
    assert re.search(r"drift\s+│ -5\.6\d\d s/day", out)
    assert re.search(r"compensating code\s+│ 5603H", out)


def test_drift_measure_apply_writes_d4054(capsys, tmp_path):
    bench = bench_with_crystal(tmp_path, 39.12)  # ≈ +3.38 s/day
    rc, out, _ = run(capsys, "drift", "measure", "emulator", "--duration", "86400", "--bench", str(bench), "--apply")
    assert rc == 0
    assert "D4054 = 56E5H (was 0000H)" in out


def test_drift_apply_over_modbus_names_address_and_map(capsys):
    rc, out, err = run(capsys, "drift", "measure", "emulator+modbus-tcp", "--duration", "100", "--apply")
    assert rc == 4 and out == ""
    assert_one_line_error(err)
    assert "D4054 cannot be reached over " + MODBUS_MAP in err and "nothing was written" in err


def test_drift_measure_too_short(capsys):
    rc, _, err = run(capsys, "drift", "measure", "emulator", "--duration", "2")
    assert rc == 4
    assert_one_line_error(err)
