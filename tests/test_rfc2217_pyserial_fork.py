"""The RFC 2217 wire works with labgrid's pyserial fork too.

labgrid depends on ``pyserial-labgrid``, which installs into the same ``serial`` package as pyserial (whichever is
installed last wins, and pip reports no conflict).  Its rfc2217.py differs in two places: a ``.timeout`` change is
not a renegotiation, and a subnegotiation whose value did not change is not sent again.  hil.io.line uses only
what both have; this test runs tests/test_rfc2217.py (settings sent once, no purge per request, the errors) in a
subprocess with the fork first on the path.  The fork is installed once into a cache directory with pip; without
the registry the test skips, saying so.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

FORK = "pyserial-labgrid"


def _cache() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "hil-tests" / FORK


def _installed_fork() -> Path:
    """The fork's ``serial`` package in the cache, installed there once (pip --target, no dependencies)."""
    target = _cache()
    if not (target / "serial" / "rfc2217.py").exists():
        proc = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                               "--no-deps", "--target", str(target), FORK],
                              capture_output=True, text=True, timeout=300)
        if proc.returncode != 0:
            pytest.skip(f"could not install {FORK} from the package registry: "
                        f"{(proc.stderr or proc.stdout).strip().splitlines()[-1:]}")
    return target


@pytest.mark.matrix  # installs the fork from the package registry: labgrid's environment, as the lab test
@pytest.mark.timeout(400)
def test_the_rfc2217_wire_works_with_pyserial_labgrid():
    fork = _installed_fork()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(fork), str(REPO)])}
    which = subprocess.run([sys.executable, "-c", "import serial; print(serial.__file__); print(serial.__version__)"],
                           capture_output=True, text=True, env=env, check=True).stdout.split()
    assert which[0].startswith(str(fork)), f"the subprocess imported serial from {which[0]}, not the fork"
    assert which[1] != "3.5", f"serial {which[1]} is stock pyserial's version, not the fork's"
    proc = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "tests" / "test_rfc2217.py"), "-q", "-p",
                           "no:cacheprovider", "-W", "ignore::DeprecationWarning"],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    last = proc.stdout.strip().splitlines()[-1]
    assert " passed" in last and "failed" not in last, proc.stdout[-2000:]  # ser2net's cases skip where it is absent
