"""A wheel, not a checkout: ``pip install .`` into a fresh environment, then ``hil run`` from another directory
finds the bundled suites and default bench profile."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def _copy_source(dest: Path) -> Path:
    """The checkout without its virtualenv, git data and build products (symlinks kept as links)."""
    ignore = shutil.ignore_patterns(".venv", ".git", "build", "*.egg-info", "__pycache__", "reports", ".hypothesis",
                                    ".pytest_cache", ".import_linter_cache", "*.so", "tests", "benchmarks")
    shutil.copytree(REPO, dest, symlinks=True, ignore=ignore)
    return dest


@pytest.mark.timeout(300)
def test_wheel_install_runs_the_bundled_suites_from_anywhere(tmp_path: Path) -> None:
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    source = _copy_source(tmp_path / "src")
    # build isolation fetches setuptools from pip's cache; no dependencies are built or installed
    built = subprocess.run([*pip, "wheel", "--no-deps", "-w", str(tmp_path / "dist"), str(source)],
                           capture_output=True, text=True, timeout=240)
    if built.returncode != 0 and "setuptools" in built.stderr and "No matching distribution" in built.stderr:
        pytest.skip(f"no setuptools for an isolated build here: {built.stderr.strip().splitlines()[-1]}")
    assert built.returncode == 0, built.stderr
    wheel = next((tmp_path / "dist").glob("hil-*.whl"))

    # A fresh environment; the dependencies (pytest, pymodbus, rich…) come from this one through a .pth file,
    # whose own .pth files (the editable hil's) are not processed: `hil` itself can only come from the wheel
    fresh = tmp_path / "fresh"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(fresh)], check=True, timeout=120)
    python = fresh / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    Path(site, "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    installed = subprocess.run([*pip, "--python", str(python), "install", "--no-deps", "--no-index", str(wheel)],
                               capture_output=True, text=True, timeout=120)
    assert installed.returncode == 0, installed.stderr

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "PYTHON"))}
    where = subprocess.run([str(python), "-c", "import hil; print(hil.__file__)"], cwd=elsewhere, env=env,
                           capture_output=True, text=True, check=True).stdout
    assert where.startswith(site), where  # the wheel's hil, not the checkout's
    done = subprocess.run([str(fresh / "bin" / "hil"), "run", "-q", "--", "-k", "smoke"], cwd=elsewhere, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "5 passed" in done.stdout, done.stdout
    cases = list(ET.parse(elsewhere / "reports" / "junit.xml").iter("testcase"))
    assert cases and all("smoke" in (c.get("name", "") + c.get("classname", "")) or c.find("skipped") is not None
                         for c in cases)
    # the same ids and JUnit classnames as a checkout's, whatever the venv's path (CI history keys on them)
    assert {c.get("classname") for c in cases} == {"suites.test_smoke"}, \
        [c.get("classname") for c in cases]

    def ids(command: list[str], cwd: Path) -> list[str]:
        listed = subprocess.run([*command, "run", "--", "--co", "-q", "-p", "no:cacheprovider"], cwd=cwd, env=env,
                                capture_output=True, text=True, timeout=120)
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
