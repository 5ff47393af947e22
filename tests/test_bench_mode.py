"""Bench mode is the product: the whole FBs suite set, slow tests included, against ``hil emulate`` as a separate
real-time process, reached only over its wires (FATEK/TCP and Modbus/TCP) and its Modbus relay rig, with a
bench-like profile (the ladder's scan counter declared).  Each run is a test with its own ``hil emulate`` (a PLC
has one plant); the gate runs the main set over FATEK/TCP, the matrix every run; the time scale is accelerated.
The gate's emulator runs in bench timing (hil.sim.timing) with a seed taken from the commit, printed with the
test's output: the suites must hold for a PLC that publishes as late as the manual allows, and a failure replays.

Every skip must name a reason a bench profile removes (a Modbus user map for D4054, [rtc] drift_max_hours for the
drift test, [bench] offers for a PLC fresh from power-on or one seen to make the spec's choices) — listed below so
that a new kind of skip fails this test.  The bench-like profile declares what a fresh ``hil emulate`` does offer.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time

import pytest

from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate

SUITES = REPO / "suites"
MAIN_SET = ["test_smoke.py", "test_rtc.py", "test_rtc_midnight.py", "test_rtc_validity.py", "test_rtc_adjust.py",
            "test_rtc_drift.py", "test_temperature.py", "test_pid.py"]
PID_CONTROL = ["test_pid_control.py"]
#: (suites, pytest's -k, time scale): the closed loop plans 35 bench minutes, so it runs at 50; the heater-loop
#: checks hold ±2 s of bench time around R4007 (80 ms of wall time at 50, where one stalled poll on a busy host
#: made them inconclusive run after run; 400 ms at 5); the rest plans a few bench minutes
RUNS = {"main": (MAIN_SET, None, 5.0), "heater-loop": (PID_CONTROL, "heater_loop", 5.0),
        "closed-loop": (PID_CONTROL, "not heater_loop", 50.0)}
#: runs whose every test must pass (the heater-loop checks: 5 tests, two in two parametrizations)
PASSES_ALL = {"heater-loop": 7}
#: what may be skipped against a separate process, and why a bench may skip it too
ALLOWED_SKIPS = [
    r"D4054 tests need D4054: D4054 cannot be reached over the default FBs Modbus map",  # a user map removes it
    r"this bench does not measure drift \(\[rtc\] drift_max_hours = 0\)",  # the profile's key removes it
    r"brackets were too wide to decide 9 vs 10",  # a busy host: the counter could not pin the scans down
    r"lower \[bench\] time_scale on this host",  # a busy host at an accelerated time scale
    r"the bench profile does not say this PLC has no RTC chip",  # the no-chip check: a profile key ([rtc] chip)
    r"slow on a real bench: pass --hil-run-slow to run it",  # the gate's non-slow set (the matrix runs them)
]
SCAN_COUNTER = "R3999"


def bench_like(text: str) -> str:
    """The emulator's profile as a bench would write it: the ladder's scan counter declared (the default profile
    has it), drift left to a bench with the hours to measure it, and what a freshly started ``hil emulate`` offers
    declared as a bench's owner would: fresh from power-on, the spec's choices."""
    assert f'scan_counter = "{SCAN_COUNTER}"' in text, "the emulator's profile declares the ladder's scan counter"
    text = text.replace("[bench]\n", '[bench]\noffers = ["power_on_state", "spec_choices"]\n', 1)
    return text.replace("[rtc]\n", "[rtc]\ndrift_max_hours = 0\n", 1)


def outcome_counts(out: str) -> dict[str, int]:
    last = [line for line in out.splitlines() if re.search(r"\d+ (passed|failed|skipped)", line)][-1]
    return {kind: int(n) for n, kind in re.findall(r"(\d+) (passed|failed|skipped|error|errors)", last)}


#: the gate runs the main set over FATEK/TCP (the bench path once); the matrix (scripts/e2e_matrix.py) every run
#: over both wires
GATE = ("main", "fatek-tcp")
#: the gate's emulator times as a bench may (hil.sim.timing): scans of 20–40 ms (never shorter than the profile's
#: 10 ms: at the accelerated time scale, shorter ones widen the scan counter's brackets; and at time scale 5, 170
#: scans a wall second rather than 330 of 10–20 ms ones, half the emulator's share of a busy CI host), readings,
#: table rewrites and PID steps at the seed's phases
BENCH_TIMING = '[emulator]\ntiming = "bench"\nscan_time_range = [20, 40]\n'
#: the gate's seed outside a git checkout (an sdist, a copied tree)
FALLBACK_SEED = 1


def commit_seed() -> int:
    """The gate's timing seed: the checked-out commit's first 32 bits (each commit its own phases, the same ones
    every time it is run again), else :data:`FALLBACK_SEED`."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return FALLBACK_SEED
    commit = head.stdout.strip()
    return int(commit[:8], 16) if head.returncode == 0 and re.fullmatch(r"[0-9a-f]{40,64}", commit) else FALLBACK_SEED


def bench_timed(text: str) -> str:
    """The profile with the gate's bench-timing keys in its [emulator] section."""
    assert text.count("[emulator]\n") == 1 and "timing =" not in text, "one [emulator] section, no timing key yet"
    return text.replace("[emulator]\n", BENCH_TIMING, 1)


@pytest.mark.e2e(leads=True)  # the gate's longest test (a minute): started first of all (tests/conftest.py)
@pytest.mark.timeout(600)  # a hang guard
@pytest.mark.parametrize("name, wire", [
    pytest.param(name, wire, marks=() if (name, wire) == GATE else pytest.mark.matrix)
    for name in RUNS for wire in ("fatek-tcp", "modbus-tcp")])
def test_the_fbs_suites_pass_against_hil_emulate_in_real_time(tmp_path, name, wire):
    emulated = tmp_path / "emulated.toml"
    text = bench_like(EMULATOR_BENCH.read_text())
    seed = None
    if (name, wire) == GATE:
        text, seed = bench_timed(text), commit_seed()
        # (pytest shows a failing test's captured output: the seed to replay it with)
        print(f"bench timing: hil emulate --timing bench --seed {seed} (replay: the same seed, this profile's "
              f"[emulator] {BENCH_TIMING.splitlines()[-1]})")
    emulated.write_text(text)
    files, selected, scale = RUNS[name]
    started = time.monotonic()
    with hil_emulate(emulated, scale, modbus=True, timing="bench" if seed is not None else None,
                     seed=seed) as where:
        bench = tmp_path / f"{name}-{wire}.toml"
        bench.write_text(bench_over_the_wire(emulated.read_text(), where, scale, wire))
        done = processes.run(
            [sys.executable, "-m", "pytest", *(str(SUITES / f) for f in files), "--bench", str(bench),
             # (the gate: the non-slow set, as a bench runs it by default; the matrix runs the slow tests too)
             *(() if seed is not None else ("--hil-run-slow",)), "-q", "-rsfE", "-p", "no:cacheprovider",
             "-p", "no:hypothesispytest",
             *(("-k", selected) if selected else ())],
            stderr=subprocess.STDOUT, cwd=tmp_path, env={**os.environ, "PYTHONUNBUFFERED": "1"}, timeout=540)
    out = done.stdout
    counts = outcome_counts(out)
    print(f"bench mode: {name} over {wire} took {time.monotonic() - started:.1f} s: {counts}")
    assert counts.get("failed", 0) == 0 and counts.get("error", 0) + counts.get("errors", 0) == 0, out[-6000:]
    assert counts.get("passed", 0) > 0, out[-3000:]
    assert counts.get("passed", 0) == PASSES_ALL.get(name, counts.get("passed")), f"{name}/{wire}: {counts}"
    for line in out.splitlines():
        if line.startswith("SKIPPED"):
            assert any(re.search(allowed, line) for allowed in ALLOWED_SKIPS), f"{name}/{wire}: {line}"
