"""Bench time of the non-slow FBs suites at time scale 1: ``hil emulate`` in real time as a separate process (a
PLC on a wire: it scans on its own and answers at scan boundaries), reached over FATEK/TCP — or over its pty paced
at a serial line's rate (``line="9600 7E1"``: port 0's factory setting, every character its 10 bits' time) — with
its relay rig and a bench-like profile (scan counter declared).  Per suite file: wall seconds, tests, skips.
Target ≤ 3 min."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.figures import record as record_figure  # noqa: E402
from hil.bench.profile import load_profile  # noqa: E402
from hil.cli.emulate import client_target  # noqa: E402
from hil.sim.pacing import LineRate  # noqa: E402
from tests.external import bench_over_the_wire, emulate_process  # noqa: E402
from tests.test_bench_mode import MAIN_SET, bench_like  # noqa: E402

SUITES = ROOT / "suites"
PROFILE = ROOT / "fixtures" / "benches" / "emulator.toml"
#: the emulator was just started: let its modules measure every point once (a 16TC at 0.1 °: 6 s) before the
#: clock starts, as a bench PLC has long been on when a run begins
WARM_UP_S = 7.0


def bench_times(time_scale: float = 1.0, files: list[str] | None = None, line: str | None = None,
                lanes: int = 1, timing: str | None = None, seed: int | None = None,
                scan_range_ms: tuple[float, float] | None = None) -> dict:
    """One pytest session over the non-slow FBs suite files, as ``hil run`` would run them on a bench: the total
    wall time, and per suite file the tests' own time (setup, call and teardown, from the JUnit report).  ``line``
    ("9600 7E1"): over ``hil emulate``'s FATEK pty paced at that rate instead of FATEK/TCP — port 0, whose rule
    the bench then declares (``[bench] answers_at_scan_end``).  ``lanes`` > 1: as ``hil run --lanes N``.
    ``timing``/``seed``: ``hil emulate --timing bench --seed N`` (hil.sim.timing), with scans of
    ``scan_range_ms`` (``[emulator] scan_time_range``)."""
    files = files or sorted(MAIN_SET)  # as hil run collects the suites' directory: by file name
    out: dict = {"time_scale": time_scale, "per_suite": {}, "lanes": lanes, "timing": timing or "instant",
                 "seed": seed, "scan_time_range_ms": scan_range_ms,
                 "wire": f"FATEK pty at {line}" if line else "FATEK/TCP"}
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        emulated = tmp_path / "emulated.toml"
        text = bench_like(PROFILE.read_text())
        if line:
            text = text.replace("[emulator]\n", f'[emulator]\nline = "{line}"\n', 1)
        if timing:
            text = text.replace("[emulator]\n", f'[emulator]\ntiming = "{timing}"\n', 1)
        if scan_range_ms:
            low, high = scan_range_ms
            text = text.replace("[emulator]\n", f"[emulator]\nscan_time_range = [{low}, {high}]\n", 1)
        emulated.write_text(text)
        wires = {"fatek-serial" if line else "fatek-tcp": "--fatek-serial" if line else "--fatek-tcp",
                 "rig-modbus-tcp": "--rig-modbus-tcp"}
        with emulate_process(emulated, time_scale, wires, seed=seed) as where:
            # the paced pty's target as hil emulate tells a user to paste it (its line's settings and station)
            url = client_target("fatek-serial", where["fatek-serial"], load_profile(emulated)) if line else None
            bench = tmp_path / "bench.toml"
            text = bench_over_the_wire(emulated.read_text(), where, time_scale, url=url)
            if line:  # the emulated port 0 services each request at a scan's end, as the manual says port 0 does
                text = text.replace("[bench]\n", "[bench]\nanswers_at_scan_end = true\n", 1)
            bench.write_text(text)
            junit = tmp_path / "junit.xml"
            time.sleep(WARM_UP_S / time_scale)
            started = time.monotonic()
            spread = ["-n", str(lanes), "--dist", "each"] if lanes > 1 else []  # hil run --lanes N
            done = subprocess.run([sys.executable, "-m", "pytest", *(str(SUITES / name) for name in files),
                                   "--bench", str(bench), "-q", "-rfE", "-p", "no:cacheprovider",
                                   f"--junitxml={junit}", *spread], cwd=tmp_path, capture_output=True, text=True)
            out["total_wall_s"] = round(time.monotonic() - started, 1)
            if done.returncode:  # a timing is worth little without why a test failed: pytest's failures, kept
                out["pytest_output_tail"] = done.stdout.splitlines()[-80:]
        cases = list(ET.parse(junit).getroot().iter("testcase"))
        slowest = sorted(cases, key=lambda c: -float(c.get("time", 0)))
        out["slowest"] = {f"{c.get('classname', '').rsplit('.', 1)[-1]}::{c.get('name')}": float(c.get("time", 0))
                          for c in slowest[:8]}
        out["per_test"] = {f"{c.get('classname', '').rsplit('.', 1)[-1]}::{c.get('name')}": float(c.get("time", 0))
                           for c in slowest}
        # what each test put on the wire (hil.plugin.perf's JUnit properties): round trips and bytes
        out["per_test_wire"] = {f"{c.get('classname', '').rsplit('.', 1)[-1]}::{c.get('name')}": {
            p.get("name"): p.get("value") for p in c.iter("property") if p.get("name") in ("hil_requests",
                                                                                           "hil_wire_bytes")}
            for c in slowest}
        for case in cases:
            name = Path(case.get("file") or case.get("classname", "").replace(".", "/") + ".py").name
            row = out["per_suite"].setdefault(name, {"tests": 0, "failures": 0, "skipped": 0, "test_time_s": 0.0,
                                                     "wire_bytes": 0, "requests": 0})
            row["tests"] += 1
            row["failures"] += case.find("failure") is not None or case.find("error") is not None
            row["skipped"] += case.find("skipped") is not None
            row["test_time_s"] = round(row["test_time_s"] + float(case.get("time", 0)), 1)
            wire = {p.get("name"): p.get("value") for p in case.iter("property")}
            row["wire_bytes"] += int(wire.get("hil_wire_bytes") or 0)  # both directions, every frame
            row["requests"] += int(wire.get("hil_requests") or 0)
        if line:  # what the characters alone cost on that line: the part of the time no poll plan can save
            rate = LineRate.parse(line)
            per_char = rate.bits / rate.baudrate
            for row in out["per_suite"].values():
                row["characters_s"] = round(row["wire_bytes"] * per_char, 1)
    return out


def record(result: dict, name: str) -> Path:
    """``result`` as docs/figures/bench-time-NAME.json (:func:`benchmarks.figures.record`)."""
    return record_figure({k: v for k, v in result.items() if k != "pytest_output_tail"}, f"bench-time-{name}")


if __name__ == "__main__":
    import argparse
    import json
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("time_scale", nargs="?", type=float, default=1.0)
    parser.add_argument("--line", help='pace the FATEK pty at this rate ("9600 7E1") instead of FATEK/TCP')
    parser.add_argument("--lanes", type=int, default=1, help="as hil run --lanes N")
    parser.add_argument("--timing", choices=("instant", "bench"), help="hil emulate --timing")
    parser.add_argument("--seed", type=int, help="hil emulate --seed")
    parser.add_argument("--scan-range", type=float, nargs=2, metavar=("MIN_MS", "MAX_MS"),
                        help="[emulator] scan_time_range (bench timing)")
    parser.add_argument("--record", metavar="NAME",
                        help="also write the result to docs/figures/bench-time-NAME.json, which the documentation "
                             "site's performance page shows (docs/_ext/hil_docs.py): figures never edited by hand")
    parser.add_argument("files", nargs="*", help="suite files (default: the non-slow main set)")
    args = parser.parse_intermixed_args()
    result = bench_times(args.time_scale, files=args.files or None, line=args.line, lanes=args.lanes,
                         timing=args.timing, seed=args.seed,
                         scan_range_ms=tuple(args.scan_range) if args.scan_range else None)
    print(json.dumps(result, indent=1))
    if args.record:
        record(result, args.record)
    total = result["total_wall_s"]
    failures = sum(row["failures"] for row in result["per_suite"].values())
    print(f"non-slow FBs suites at time scale {result['time_scale']} ({result['wire']}, {result['timing']} timing"
          f"{', seed ' + str(result['seed']) if result['seed'] is not None else ''}): {total:.0f} s "
          f"({'within' if total <= 180 else 'over'} the 3 min target), {failures} failed", file=sys.stderr)
