"""``hil init`` (issue 29, point 5): a bench profile and a first test, filled in from what the PLC says, with
placeholders for what it cannot say; against ``hil emulate`` the profile it writes runs the bundled suites."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hil.bench.profile import load_profile
from hil.cli.main import EXIT_USAGE, main
from tests.conftest import EMULATOR_BENCH
from tests.external import emulate_process

TIME_SCALE = 5


def _outcomes(junit: Path) -> dict[str, str]:
    out = {}
    for case in ET.parse(junit).iter("testcase"):
        bad = case.find("failure") is not None or case.find("error") is not None
        out[f"{case.get('classname')}::{case.get('name')}"] = (
            "skipped" if case.find("skipped") is not None else "failed" if bad else "passed")
    return out


def test_init_fills_in_what_the_plc_says_and_leaves_placeholders(tmp_path: Path, capsys) -> None:
    assert main(["init", "emulator", "--dir", str(tmp_path), "--temperature-table", "R3000", "--name", "line 3"]) == 0
    text = (tmp_path / "bench.toml").read_text()
    profile = load_profile(tmp_path / "bench.toml")
    assert profile.name == "line 3" and profile.target == "emulator"
    assert profile.rtc.chip == 3 and "D4053 = 3" in text  # read from the PLC
    temperature = profile.sections["temperature"]
    assert (str(temperature.table), str(temperature.readings), str(temperature.work)) == ("R3000", "R3020", "R3060")
    assert [(m.type.name, m.sensor.name) for m in temperature.modules] == [("16TC", "K"), ("16TC", "J")]
    assert "R4128-R4134" in profile.safety.writable and "D4054" in profile.safety.writable
    assert "pid" not in profile.sections and "# [[pid.instances]]" in text  # what it cannot read: a placeholder
    assert "# scratch = " in text and "PLC status: RUN" in text
    assert (tmp_path / "tests" / "test_first.py").is_file()

    # nothing overwritten without --force: one line, exit 4
    assert main(["init", "emulator", "--dir", str(tmp_path)]) == EXIT_USAGE
    assert "already exist" in capsys.readouterr().err


@pytest.mark.parametrize("planted", ["bench.toml", "tests/test_first.py"])
@pytest.mark.parametrize("force", [False, True], ids=["", "force"])
def test_init_writes_nothing_through_a_symbolic_link(tmp_path: Path, capsys, planted: str, force: bool) -> None:
    """Issue 40 item 13: a dangling link where the profile goes made hil init write the profile where it pointed."""
    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    (work / "tests").mkdir(parents=True)
    elsewhere.mkdir()
    (work / planted).symlink_to(elsewhere / "victim")
    assert main(["init", "emulator", "--dir", str(work), *(["--force"] if force else [])]) == EXIT_USAGE
    said = " ".join(capsys.readouterr().err.split())
    assert f"{work / planted} is a symbolic link (to {elsewhere / 'victim'})" in said and "remove the link" in said
    assert not (elsewhere / "victim").exists() and list(elsewhere.iterdir()) == []
    assert sorted(p.name for p in work.rglob("*") if not p.is_symlink()) == ["tests"]  # nothing written at all


def test_init_names_the_bench_by_its_directory_and_takes_scratch_ranges(tmp_path: Path) -> None:
    """Two profiles for one address are two benches in the history (the name keys it): the default name is the
    directory's, not the URL.  --scratch fills [bench] scratch and the allow-list, so the smoke suite's round trips
    run from the first run on; the hint after it is one command a line, unwrapped in a pipe (80 columns)."""
    for where in ("oven-line-1", "oven-line-2"):
        done = subprocess.run([sys.executable, "-m", "hil", "init", "emulator", "--dir", str(tmp_path / where),
                               "--scratch", "R1000-R1099", "--scratch", "M1000-M1015"], capture_output=True,
                              text=True, timeout=60, cwd=tmp_path, env={**os.environ, "COLUMNS": "80"})
        assert done.returncode == 0, done.stdout + done.stderr
        profile = load_profile(tmp_path / where / "bench.toml")
        assert profile.name == where
        assert profile.scratch == ("R1000-R1099", "M1000-M1015")
        assert profile.can_write("R1000") and profile.can_write("M1015") and not profile.can_write("R1100")
        lines = done.stdout.splitlines()
        assert f"  cd {tmp_path / where} && hil run --bench bench.toml -- tests" in lines, done.stdout
        assert f"  cd {tmp_path / where} && hil run --bench bench.toml" in lines, done.stdout
    refused = subprocess.run([sys.executable, "-m", "hil", "init", "emulator", "--dir", str(tmp_path / "x"),
                              "--scratch", "R99999"], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert refused.returncode == EXIT_USAGE and "--scratch 'R99999'" in refused.stderr, refused.stderr
    assert not (tmp_path / "x" / "bench.toml").exists()


def test_init_says_why_a_table_is_not_there(tmp_path: Path) -> None:
    assert main(["init", "emulator", "--dir", str(tmp_path), "--temperature-table", "R100"]) == 0
    text = (tmp_path / "bench.toml").read_text()
    assert "# no temperature table at R100: R100 = 0000H, not the marker A556H" in text, text
    assert "temperature" not in load_profile(tmp_path / "bench.toml").sections


@pytest.mark.matrix  # the gate runs hil init's profile against hil emulate in tests/test_docs.py (smoke)
@pytest.mark.timeout(240)
def test_the_profile_init_writes_against_hil_emulate_runs_the_bundled_suites(tmp_path: Path) -> None:
    python = [sys.executable, "-m", "hil"]
    with emulate_process(EMULATOR_BENCH, TIME_SCALE, {"fatek-tcp": "--fatek-tcp"}) as where:
        url = f"fatek+tcp://{where['fatek-tcp']}"
        made = subprocess.run([*python, "init", url, "--temperature-table", "R3000", "--time-scale", str(TIME_SCALE)],
                              cwd=tmp_path, capture_output=True, text=True, timeout=60)
        assert made.returncode == 0, made.stdout + made.stderr
        suites = subprocess.run([*python, "run", "--bench", "bench.toml"], cwd=tmp_path, capture_output=True,
                                text=True, timeout=200)
        assert suites.returncode == 0, suites.stdout[-4000:] + suites.stderr
        ran = _outcomes(tmp_path / "reports" / "junit.xml")
        first = subprocess.run([*python, "run", "--bench", "bench.toml", "--", "tests"], cwd=tmp_path,
                               capture_output=True, text=True, timeout=60)
        assert first.returncode == 0, first.stdout[-4000:] + first.stderr
    assert "failed" not in ran.values()
    # what init read from the PLC is what these need: the RTC and temperature suites ran, not skipped
    passed = {name.split("::")[0] for name, outcome in ran.items() if outcome == "passed"}
    assert {"suites.test_rtc", "suites.test_rtc_validity", "suites.test_temperature"} <= passed, passed
    assert set(_outcomes(tmp_path / "reports" / "junit.xml").values()) == {"passed"}
