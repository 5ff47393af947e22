"""A wheel, not a checkout: ``pip install .`` into a fresh environment, then ``hil run`` from another directory
finds the bundled suites and default bench profile."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.wheel_venv import REPO, Installed, installed_hil_fixture  # noqa: F401 - the installed_hil fixture


@pytest.mark.timeout(300)
def test_wheel_install_runs_the_bundled_suites_from_anywhere(installed_hil: Installed, tmp_path: Path) -> None:
    fresh, python, site, env = installed_hil.root / "fresh", installed_hil.python, installed_hil.site, installed_hil.env
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    where = subprocess.run([str(python), "-c", "import hil; print(hil.__file__)"], cwd=elsewhere, env=env,
                           capture_output=True, text=True, check=True).stdout
    assert where.startswith(site), where  # the wheel's hil, not the checkout's
    done = subprocess.run([str(fresh / "bin" / "hil"), "run", "-v", "--", "-k", "smoke", "-rA"], cwd=elsewhere,
                          env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "5 passed" in done.stdout, done.stdout
    # the console names each test as `hil run -- ID` takes it back, not by a path up to the installed package
    assert "\nsuites/test_smoke.py::test_plc_answers_status PASSED" in done.stdout, done.stdout
    assert "PASSED suites/test_smoke.py::test_plc_answers_status" in done.stdout, done.stdout  # -rA's summary
    assert "_data/suites/test_smoke.py::" not in done.stdout, done.stdout
    cases = list(ET.parse(elsewhere / "reports" / "junit.xml").iter("testcase"))
    assert cases and all("smoke" in (c.get("name", "") + c.get("classname", "")) or c.find("skipped") is not None
                         for c in cases)
    # the same ids and JUnit classnames as a checkout's, whatever the venv's path (CI history keys on them)
    assert {c.get("classname") for c in cases} == {"suites.test_smoke"}, \
        [c.get("classname") for c in cases]

    def ids(command: list[str], cwd: Path) -> list[str]:
        # the reports in this test's directory: the checkout's reports/ is the user's, never the tests'
        reports = ["--junitxml", str(tmp_path / "ids" / "junit.xml"), "--html", str(tmp_path / "ids" / "report.html")]
        listed = subprocess.run([*command, "run", *reports, "--", "--co", "-q", "-p", "no:cacheprovider"], cwd=cwd,
                                env=env, capture_output=True, text=True, timeout=120)
        assert listed.returncode == 0, listed.stdout + listed.stderr
        return [line for line in listed.stdout.splitlines() if "::" in line]

    installed, checkout = ids([str(fresh / "bin" / "hil")], elsewhere), ids([sys.executable, "-m", "hil"], REPO)
    assert installed == checkout and installed[0].startswith("suites/"), (installed[:3], checkout[:3])

    # bundled profiles and suites by short name, listed by a command; the README's paths work once installed
    listed = subprocess.run([str(fresh / "bin" / "hil"), "list"], cwd=elsewhere, env=env, capture_output=True,
                            text=True, timeout=60)
    assert listed.returncode == 0 and "s7-200smart" in listed.stdout and "rtc_validity" in listed.stdout
    for argv, says in ((["--bench", "s7-200smart", "--", "s7_smoke"], "passed"),
                       (["--", "rtc_adjust", "--co", "-q"], "suites/test_rtc_adjust.py::"),
                       (["--", "suites/test_rtc.py", "--co", "-q"], "suites/test_rtc.py::"),
                       (["--bench", "fixtures/benches/s7-200smart.toml", "--", "s7smart", "--co", "-q"],
                        "suites/s7smart/test_s7_rtc.py::")):
        done = subprocess.run([str(fresh / "bin" / "hil"), "run", *argv], cwd=elsewhere, env=env,
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and says in done.stdout, argv + [done.stdout[-2000:], done.stderr]
