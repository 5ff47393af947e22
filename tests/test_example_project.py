"""Issue 29's acceptance: the example project (examples/heat_treatment) as a user has it — its files in a directory
outside the checkout, hil installed from a wheel into a fresh venv — runs with ``hil run -- …`` and with plain
pytest on the in-process emulator and against ``hil emulate`` in real time (accelerated); a broken-emulator
variant of the oven makes the pre-alarm test fail, and only it; ``pytest --fixtures`` there lists every shipped
fixture with its docstring; and mypy --strict passes on the example through the installed package (py.typed)."""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests import processes
from tests.external import _read_endpoints
from tests.wheel_venv import REPO, Installed, installed_hil_fixture  # noqa: F401 - the installed_hil fixture

EXAMPLE = REPO / "examples" / "heat_treatment"
TESTS = ("test_a_set_point_step_settles_in_band", "test_the_over_temperature_pre_alarm_trips",
         "test_a_shift_change_time_in_r4135_matches_the_clock")
#: every fixture the plugin ships, with a phrase of its docstring
SHIPPED = {"bench": "behind the guard", "plc": "The PLC under test", "io": "through the", "faults": "fault injectors",
           "rtc": "real-time clock", "pid": "FUN86 boxes", "temperature": "temperature modules",
           "measure": "Record a measurement", "report": "HTML report"}
TIME_SCALE = 20  # hil emulate's: the 160 bench seconds of the example take 8 s of wall time


def _outcomes(junit: Path) -> dict[str, str]:
    out = {}
    for case in ET.parse(junit).iter("testcase"):
        failed = case.find("failure") is not None or case.find("error") is not None
        out[case.get("name", "")] = "skipped" if case.find("skipped") is not None else "failed" if failed else "passed"
    return out


def _project(tmp_path: Path) -> Path:
    project = tmp_path / "line"
    shutil.copytree(EXAMPLE, project, ignore=shutil.ignore_patterns("__pycache__", "reports", ".mypy_cache"))
    return project


@pytest.mark.e2e
@pytest.mark.timeout(300)
def test_the_example_project_runs_from_a_wheel_and_catches_a_broken_oven(installed_hil: Installed,
                                                                        tmp_path: Path) -> None:
    hil, python = installed_hil.hil, installed_hil.python
    project = _project(tmp_path)
    junit = project / "reports" / "junit.xml"

    done = installed_hil.run([hil, "run", "--bench", "bench.toml", "--", "tests"], cwd=project)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr
    assert _outcomes(junit) == dict.fromkeys(TESTS, "passed"), _outcomes(junit)

    plain = installed_hil.run([python, "-m", "pytest", "--bench", "bench.toml", "tests", "-p", "no:cacheprovider",
                               "--junitxml", "plain.xml"], cwd=project)
    assert plain.returncode == 0, plain.stdout[-3000:] + plain.stderr
    assert _outcomes(project / "plain.xml") == dict.fromkeys(TESTS, "passed")

    shutil.copy(REPO / "tests" / "example_broken_oven.py", project)
    broken = installed_hil.run([python, "-m", "pytest", "--bench", "bench.toml", "tests", "-p", "no:cacheprovider",
                                "-p", "example_broken_oven", "--junitxml", "broken.xml"], cwd=project)
    assert broken.returncode == 1, broken.stdout[-3000:] + broken.stderr
    assert _outcomes(project / "broken.xml") == {**dict.fromkeys(TESTS, "passed"),
                                                 "test_the_over_temperature_pre_alarm_trips": "failed"}

    listed = installed_hil.run([python, "-m", "pytest", "--fixtures", "-p", "no:cacheprovider"], cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    for name, says in SHIPPED.items():
        entry = re.search(rf"(?m)^{name}\b.*\n((?:    .*\n)+)", listed.stdout)
        assert entry and says in " ".join(entry.group(1).split()), (name, listed.stdout[-3000:])

    # the type check a test author's IDE does: the installed hil.api (py.typed) and the example's own code
    typed = installed_hil.run([python, "-m", "mypy", "--strict", "--no-incremental", "tests"], cwd=project,
                              timeout=180)
    assert typed.returncode == 0, typed.stdout + typed.stderr


@pytest.mark.matrix
@pytest.mark.timeout(300)
def test_the_example_project_passes_against_hil_emulate_in_real_time(installed_hil: Installed,
                                                                     tmp_path: Path) -> None:
    project = _project(tmp_path)
    emulate = processes.spawn([str(installed_hil.hil), "emulate", "--no-live", "--bench", "bench.toml",
                                "--fatek-tcp", "127.0.0.1:0", "--time-scale", str(TIME_SCALE)], cwd=project,
                               env=installed_hil.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        where = _read_endpoints(emulate, {"fatek-tcp"}, timeout=30)
        text = (project / "bench.toml").read_text()
        text = re.sub(r'(?m)^target = "emulator"', f'target = "fatek+tcp://{where["fatek-tcp"]}"', text)
        text = re.sub(r"(?m)^time_scale = .*", f"time_scale = {TIME_SCALE}", text)
        (project / "wire.toml").write_text(text)
        done = installed_hil.run([installed_hil.hil, "run", "--bench", "wire.toml", "--", "tests"], cwd=project,
                                 timeout=240)
    finally:
        emulate.send_signal(signal.SIGINT)
        try:
            emulate.wait(timeout=30)
        except subprocess.TimeoutExpired:
            emulate.kill()
            emulate.wait()
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr
    assert _outcomes(project / "reports" / "junit.xml") == dict.fromkeys(TESTS, "passed")
    assert emulate.returncode == 0, emulate.stderr.read() if emulate.stderr else ""
