"""The broken-PLC defects (RTC, temperature, FUN86) against ``hil emulate`` as a separate real-time process with a
bench-like profile (scan counter declared), reached only over FATEK/TCP and the Modbus relay rig: each defect must
fail at least one suite test there too, as it would on a bench.  Each defect gets its own ``hil emulate``
(tests/broken_emulate.py); several run in parallel, in three tests that pytest-xdist spreads over its workers.  Only the
suite tests the in-process broken-PLC tests name as catching a defect run (RTC: the RTC suites, stopping at the first
failure), to keep CI short.
"""

from __future__ import annotations

import concurrent.futures
import importlib
import os
import re
import subprocess
import sys
import time

import pytest

from tests import test_pid_suites as pid_defects
from tests import test_rtc_suites_catch_broken_plcs as rtc_defects
from tests import test_temperature_suites as temperature_defects
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate
from tests.test_bench_mode import bench_like

SUITES = REPO / "suites"
TIME_SCALE = 10.0
#: FUN86 defects that show only between an edge and the next PID interval need finer bench time on a busy host
PID_TIME_SCALE = 5.0
#: scan-exact defects run in real time (10 ms scans): requests must be quicker than scans for the counter to pin
#: the scans down, as on a bench PLC's port 0; so must the sampling of an output right after a disable (the
#: broken PLC drives it only until its next PID step: the first sample, a few ms after, sees it unless a step
#: falls in those ms of the 4 s interval)
REAL_TIME = {"PrealarmAfter9Scans", "PrealarmAfter11Scans", "DipDoesNotResetTheCount", "DisabledPointStillDriven",
             "R4013Ignored"}
#: shows only while the modules measure every point for the first time (6 bench s from power-on): the emulator runs
#: slower than real time, so the start of hil emulate and of pytest on a busy CI host fits in that first measurement
SLOWER_THAN_REAL_TIME = {"ActsBeforeMeasured": 0.3}
#: caught by the drift tests, which need bench hours: the direction check with the largest code (4 s/day) gets
#: them at a high time scale, with [rtc] drift_max_hours given (the fine-step test would need far more)
NEEDS_DRIFT_HOURS = {"D4054SignInverted", "D4054NegativeCodesIgnored", "D4054NegativeCodesInverted",
                     "D4054DroppedAtASet"}
#: caught only when the set and the M1953 edge come within the one chip second from :59 to the next minute
RTC_REAL_TIME = {"AdjustWindowEndsAt58"}
DRIFT_TIME_SCALE = 100.0
DRIFT_HOURS = 2.0


#: a whole-domain defect must be failed by its own test (named in the -rf summary)
CAUGHT_BY_NAME = {cls.__name__: test for cls, test in rtc_defects.CAUGHT_BY.items()}


def _k(names: list[str]) -> str:
    return " or ".join(sorted({name.split("[")[0] for name in names}))


def _defects() -> list[tuple[str, list[str], list[str], float]]:
    """(MODULE:FACTORY:DEFECT, suite files, extra pytest arguments, time scale)."""
    found = []
    rtc_files = [str(SUITES / f) for f in rtc_defects.RTC_SUITES]
    for cls in rtc_defects.VARIANTS:
        spec = f"{rtc_defects.__name__}:with_rtc:{cls.__name__}"
        if cls.__name__ in NEEDS_DRIFT_HOURS:
            found.append((spec, [str(SUITES / "test_rtc_drift.py")], ["-k", "largest_code"], DRIFT_TIME_SCALE))
        else:
            found.append((spec, rtc_files, ["-x"], TIME_SCALE))
    for cls, name in rtc_defects.CAUGHT_BY.items():  # the whole-domain checks: only the test that must catch it
        scale = (1.0 if cls.__name__ in RTC_REAL_TIME else
                 DRIFT_TIME_SCALE if cls.__name__ in NEEDS_DRIFT_HOURS else TIME_SCALE)
        found.append((f"{rtc_defects.__name__}:with_rtc:{cls.__name__}", rtc_files, ["-k", name], scale))
    for cls, names in temperature_defects.CAUGHT_BY.items():
        found.append((f"{temperature_defects.__name__}:Variant:{cls.__name__}", [temperature_defects.SUITE],
                      ["-k", _k(names)], TIME_SCALE))
    for cls, names in pid_defects.CAUGHT_BY.items():
        found.append((f"{pid_defects.__name__}:Variant:{cls.__name__}", pid_defects.SUITES, ["-k", _k(names)],
                      SLOWER_THAN_REAL_TIME.get(cls.__name__, 1.0 if cls.__name__ in REAL_TIME else PID_TIME_SCALE)))
    return found


#: a real-time defect whose catching tests all skipped (a busy host stretched requests past the scans they must
#: pin down: the suite said "cannot decide here", not "passed") is run again, at most this many times
INCONCLUSIVE_RETRIES = 2


def _run(spec: str, files: list[str], extra: list[str], scale: float, tmp_path) -> tuple[str, dict[str, int], str]:
    name = spec.rsplit(":", 1)[1]
    for attempt in range(INCONCLUSIVE_RETRIES + 1):
        counts, out = _run_once(spec, files, extra, scale, tmp_path / f"{name}-{attempt}")
        inconclusive = not counts.get("failed") and not counts.get("passed") and counts.get("skipped")
        if not (inconclusive and scale == 1.0):
            break
    return name, counts, out


def _run_once(spec: str, files: list[str], extra: list[str], scale: float, tmp_path) -> tuple[dict[str, int], str]:
    name = spec.rsplit(":", 1)[1]
    tmp_path.mkdir()
    emulated = tmp_path / f"{name}-emulated.toml"
    profile = bench_like(EMULATOR_BENCH.read_text())
    transform = getattr(importlib.import_module(spec.split(":")[0]), "PROFILE_FOR", {}).get(name)
    if transform is not None:  # a defect another profile shows (e.g. °F)
        profile = transform(profile)
    if name in NEEDS_DRIFT_HOURS:
        profile = profile.replace("drift_max_hours = 0\n", f"drift_max_hours = {DRIFT_HOURS}\n", 1)
    if name in {cls.__name__ for cls in rtc_defects.NO_CHIP}:
        profile = rtc_defects.no_chip_profile(profile)
    emulated.write_text(profile)
    with hil_emulate(emulated, scale, broken=spec) as where:
        bench = tmp_path / f"{name}.toml"
        bench.write_text(bench_over_the_wire(emulated.read_text(), where, scale))
        done = subprocess.run([sys.executable, "-m", "pytest", *files, "--bench", str(bench), "--hil-run-slow",
                               "-q", "-rfE", "-p", "no:cacheprovider", "-p", "no:hypothesispytest", *extra],
                              capture_output=True, text=True, cwd=tmp_path, timeout=300,
                              env={**os.environ, "PYTHONUNBUFFERED": "1"})
    out = done.stdout + done.stderr
    lines = [line for line in out.splitlines() if re.search(r"\d+ (passed|failed|skipped|deselected)", line)]
    counts = {kind: int(n)
              for n, kind in re.findall(r"(\d+) (passed|failed|skipped|error)", lines[-1] if lines else "")}
    return counts, out


#: the defects in this many tests (each its own pool): pytest-xdist runs them on different workers at once, so the
#: longest test of the harness's CI is a third of what it was
PARTS = 3


#: the gate's one defect (the path: a broken ``hil emulate`` caught over the wire): an RTC defect at an accelerated
#: time scale, which no host's load can make inconclusive; the matrix (scripts/e2e_matrix.py) runs them all
GATE_DEFECT = "SetTakesLowBytesOnly"


@pytest.mark.e2e
@pytest.mark.timeout(300)
def test_a_broken_plc_fails_a_suite_test_against_hil_emulate(tmp_path):
    defects = [d for d in _defects() if d[0].endswith(f":{GATE_DEFECT}")]
    assert len(defects) == 1, [d[0] for d in _defects()]
    _assert_caught([_run(*defects[0], tmp_path)])


@pytest.mark.matrix
@pytest.mark.timeout(600)
@pytest.mark.parametrize("part", range(PARTS), ids=[f"part{k + 1}of{PARTS}" for k in range(PARTS)])
def test_every_defect_fails_a_suite_test_against_hil_emulate(tmp_path, part):
    defects = _defects()[part::PARTS]
    started = time.monotonic()
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(lambda d: _run(*d, tmp_path), defects))
    print(f"{len(defects)} broken PLCs against hil emulate in {time.monotonic() - started:.1f} s")
    _assert_caught(results)


def _assert_caught(results: list[tuple[str, dict[str, int], str]]) -> None:
    uncaught = []
    for name, counts, out in results:
        print(f"{name}: {counts}")
        if counts.get("failed", 0) == 0 or (name in CAUGHT_BY_NAME and CAUGHT_BY_NAME[name] not in out):
            uncaught.append(f"{name}: {counts}\n{out[-1500:]}")
    assert not uncaught, "defects no suite test catches on a bench:\n" + "\n".join(uncaught)
