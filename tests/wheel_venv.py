"""hil installed from a wheel into a fresh environment, outside the checkout: built once per test run and shared by
the tests that need it (tests/test_packaging.py, tests/test_example_project.py), also across xdist workers (a lock
file in the run's shared temporary directory: the first worker builds, the others wait and reuse it)."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Installed:
    """A fresh venv with hil from the wheel; its dependencies come from this environment through a .pth file."""

    root: Path
    python: Path
    site: str

    @property
    def hil(self) -> Path:
        return self.python.parent / "hil"

    @property
    def env(self) -> dict[str, str]:
        """This process's environment without what would make the fresh venv's Python find the checkout."""
        return {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "PYTHON"))}

    def run(self, argv: list[str | Path], cwd: Path, timeout: float = 120, **extra_env: str
            ) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(a) for a in argv], cwd=cwd, env={**self.env, **extra_env}, capture_output=True,
                              text=True, timeout=timeout)


def _copy_source(dest: Path) -> Path:
    """The checkout without its virtualenv, git data and build products (symlinks kept as links)."""
    ignore = shutil.ignore_patterns(".venv*", ".git", "build", "*.egg-info", "__pycache__", "reports", ".hypothesis",
                                    ".pytest_cache", ".import_linter_cache", ".mypy_cache", "*.so", "tests",
                                    "benchmarks", "examples")
    shutil.copytree(REPO, dest, symlinks=True, ignore=ignore)
    return dest


def _build(root: Path) -> dict[str, str]:
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    source = _copy_source(root / "src")
    # build isolation fetches setuptools from pip's cache; no dependencies are built or installed
    built = subprocess.run([*pip, "wheel", "--no-deps", "-w", str(root / "dist"), str(source)],
                           capture_output=True, text=True, timeout=240)
    if built.returncode != 0 and "setuptools" in built.stderr and "No matching distribution" in built.stderr:
        return {"skip": f"no setuptools for an isolated build here: {built.stderr.strip().splitlines()[-1]}"}
    if built.returncode != 0:
        return {"error": f"pip wheel failed: {built.stderr}"}
    wheel = next((root / "dist").glob("hil-*.whl"))
    # A fresh environment; the dependencies (pytest, pymodbus, rich…) come from this one through a .pth file,
    # whose own .pth files (the editable hil's) are not processed: `hil` itself can only come from the wheel
    fresh = root / "fresh"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(fresh)], check=True, timeout=120)
    python = fresh / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    Path(site, "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    installed = subprocess.run([*pip, "--python", str(python), "install", "--no-deps", "--no-index", str(wheel)],
                               capture_output=True, text=True, timeout=120)
    if installed.returncode != 0:
        return {"error": f"pip install of {wheel.name} failed: {installed.stderr}"}
    return {"python": str(python), "site": site}


@pytest.fixture(scope="session", name="installed_hil")
def installed_hil_fixture(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    """hil from a wheel in a fresh venv (built once per run, whichever worker asks first)."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    root = shared / "hil-wheel"
    with open(shared / "hil-wheel.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        made = root / "made.json"
        if not made.exists():
            root.mkdir(exist_ok=True)
            made.write_text(json.dumps(_build(root)))
        result = json.loads(made.read_text())
    if "skip" in result:
        pytest.skip(result["skip"])
    assert "error" not in result, result["error"]
    return Installed(root, Path(result["python"]), result["site"])


__all__ = ["Installed", "REPO", "installed_hil_fixture"]
