"""Bench time of the non-slow FBs suites at time scale 1: ``hil emulate`` in real time as a separate process (a
PLC on a wire: it scans on its own and answers at scan boundaries), reached over FATEK/TCP with its relay rig and
a bench-like profile (scan counter declared).  Per suite file: wall seconds, tests, skips.  Target ≤ 3 min."""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.external import bench_over_the_wire, hil_emulate  # noqa: E402
from tests.test_bench_mode import MAIN_SET, bench_like  # noqa: E402

SUITES = ROOT / "suites"
PROFILE = ROOT / "fixtures" / "benches" / "emulator.toml"


def bench_times(time_scale: float = 1.0, files: list[str] | None = None) -> dict:
    files = files or MAIN_SET
    out: dict = {"time_scale": time_scale, "per_suite": {}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        emulated = tmp_path / "emulated.toml"
        emulated.write_text(bench_like(PROFILE.read_text()))
        with hil_emulate(emulated, time_scale) as where:
            bench = tmp_path / "bench.toml"
            bench.write_text(bench_over_the_wire(emulated.read_text(), where, time_scale))
            started = time.monotonic()
            for name in files:
                junit = tmp_path / f"{name}.xml"
                t0 = time.monotonic()
                subprocess.run([sys.executable, "-m", "pytest", str(SUITES / name), "--bench", str(bench), "-q",
                                "-p", "no:cacheprovider", f"--junitxml={junit}"], cwd=tmp_path,
                               capture_output=True, text=True)
                wall = time.monotonic() - t0
                suite = ET.parse(junit).getroot()
                suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
                out["per_suite"][name] = {"wall_s": round(wall, 1), "tests": int(suite.get("tests", 0)),
                                          "failures": int(suite.get("failures", 0)) + int(suite.get("errors", 0)),
                                          "skipped": int(suite.get("skipped", 0)),
                                          "test_time_s": round(float(suite.get("time", 0)), 1)}
            out["total_wall_s"] = round(time.monotonic() - started, 1)
    return out


if __name__ == "__main__":
    import json
    result = bench_times(float(sys.argv[1]) if len(sys.argv) > 1 else 1.0)
    print(json.dumps(result, indent=1))
    total = result["total_wall_s"]
    print(f"non-slow FBs suites at time scale {result['time_scale']}: {total:.0f} s "
          f"({'within' if total <= 180 else 'over'} the 3 min target)", file=sys.stderr)
