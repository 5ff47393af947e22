"""The exhaustive real-time matrix: ``python scripts/e2e_matrix.py`` (from the project directory, with .venv made as
README's first command makes it; about 8 minutes on a 2-core host).

What the gate (``.ci/run``) runs once per path, this runs in full: every defect of the broken-PLC variants against
``hil emulate`` over the wire, the FBs suite set on both wires and every time scale, kills and recoveries at 13
moments in three lanes (FBs) and of the S7 suites, ten runs that set the clock (offset in ms), the soak over every
wire, every plant, RFC 2217 with both protocols and labgrid's pyserial fork, the example project in real time, and
a lab of benches through a real labgrid coordinator and exporter (in ``.venv-labgrid``, made here if missing).

These are the tests marked ``matrix`` (deselected by the gate) and ``e2e`` (the gate's real-time tests), run by
pytest with ``--matrix``.  The outcome and the wall time go to ``reports/e2e-matrix.json`` (a generated file).
Arguments after ``--`` go to pytest (e.g. ``-- -k kill``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PYTHON = ROOT / ".venv" / "bin" / "python"
LABGRID_VENV = ROOT / ".venv-labgrid"


def labgrid_environment() -> str | None:
    """.venv-labgrid with ``hil[labgrid]`` (labgrid's pyserial fork must not replace .venv's pyserial), made from a
    copy of the tracked tree; None when it is there, else why it could not be made (the lab tests then skip)."""
    if (LABGRID_VENV / "bin" / "labgrid-coordinator").is_file():
        return None
    subprocess.run([sys.executable, "-m", "venv", str(LABGRID_VENV)], check=True)
    with tempfile.TemporaryDirectory() as copy:
        files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        for name in filter(None, files.decode().split("\0")):
            target = Path(copy, name)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, target, follow_symlinks=False)
        done = subprocess.run([str(LABGRID_VENV / "bin" / "pip"), "install", "--quiet", "--no-compile",
                               "--disable-pip-version-check", f"{copy}[labgrid]"], capture_output=True, text=True)
    if done.returncode != 0:
        shutil.rmtree(LABGRID_VENV, ignore_errors=True)
        return f"could not install hil[labgrid]: {done.stderr.strip().splitlines()[-1:]}"
    return None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", "--workers", default="2", help="pytest-xdist workers (default 2: real-time tests "
                                                            "share the host's cores with the emulators they start)")
    parser.add_argument("--no-labgrid", action="store_true", help="do not make .venv-labgrid (the lab tests skip)")
    parser.add_argument("pytest_args", nargs="*", help="more arguments for pytest (after --)")
    args = parser.parse_args()
    if not PYTHON.is_file():
        parser.error(f"{PYTHON} is missing: make it with README's first command")
    if not args.no_labgrid and (why := labgrid_environment()):
        print(f"{why}: tests/test_lab_of_benches.py skips with the reason")
    results = Path(tempfile.mkdtemp(prefix="hil-e2e-matrix-")) / "junit.xml"
    started = time.monotonic()
    done = subprocess.run([str(PYTHON), "-m", "pytest", "tests", "--matrix", "-m", "e2e or matrix", "-n",
                           args.workers, "-p", "no:randomly", "-rfEs", f"--junitxml={results}",
                           *args.pytest_args], cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    elapsed = time.monotonic() - started
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    if results.exists():
        for suite in ET.parse(results).iter("testsuite"):
            for key in counts:
                counts[key] += int(suite.get(key, 0))
    summary = {"exit_code": done.returncode, "wall_seconds": round(elapsed, 1), "workers": args.workers,
               "cpus": os.cpu_count(), **counts, "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    out = ROOT / "reports" / "e2e-matrix.json"
    out.write_text(json.dumps(summary, indent=2) + "\n")
    print(f"the real-time matrix: {counts['tests']} tests in {elapsed:.0f} s, exit {done.returncode} ({out})")
    return done.returncode


if __name__ == "__main__":
    sys.exit(main())
