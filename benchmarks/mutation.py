"""Mutation testing of the emulator's models with cosmic-ray 8.7: do the suites notice when a model is wrong?

    python benchmarks/mutation.py --quick        # a fixed sample of 100 mutants (≤ 10 min on two cores)
    python benchmarks/mutation.py --sample 400   # a larger fixed sample
    python benchmarks/mutation.py                # every mutant (≈ 5000: hours; not in CI)

Mutated: hil/families/fbs/sim/models/{rtc,temperature,temperature_readings,fun86,fun86_law,fun86_pwm,fun86_alarms}.py
(the models as they were before their scans were split by the manual's steps, issue 41) and the S7-200 SMART clock model
(hil/families/s7smart/sim/clock.py).  The test command is the suites against the in-process emulator, exactly as
``hil run`` runs them (the slow tests included: virtual time), stopping at the first failure: for each model the
suites that can see it (RTC: the four RTC suites; temperature: the temperature and PID suites, FUN86 reads the
temperatures, and the temperature suite once more on the profile with averaging and the fast rate and once on the
default profile with 2-sample averaging; FUN86: the PID suites; S7: suites/s7smart with the S7-200 SMART profile, as an
ST40 and as a CR40).  The FBs models' sessions then run tests/test_fast_forward.py, only once the suites pass: it
compares the emulator with itself, virtual time jumped and stepped scan by scan (the same memory, every change of
FUN86's outputs at the same scan, the jump a fraction of the scans, a long jump's catch-up bounded), so it judges
only the models' scheduling for the in-process engine (``next_event`` and what only it uses), which no bench's wire
can show; a mutant of behaviour changes both runs alike and passes it, so behaviour is still judged by the suites
alone.  cosmic-ray writes each mutant into the
files it tests, so the work happens in a scratch copy of the working tree (PYTHONPATH points the suites at it); the
checkout is never touched.

Every surviving mutant is looked up in ``benchmarks/mutation-survivors.toml`` (keyed by file, operator and the
mutated line's text, so the classification survives unrelated edits): *equivalent*, *choice* (an [our choice] the
suites rightly leave open), *not_observable* (no bench's wire can show it), or *gap* (a suite should catch it).
The score is killed / (mutants run − equivalent); an unclassified survivor is listed and counted as a gap.
The report goes to reports/mutation/: score.json and survivors.md (each survivor's diff and classification).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.figures import record as record_figure  # noqa: E402

MODELS = "hil/families/fbs/sim/models/"
RTC_SUITES = ("suites/test_rtc.py suites/test_rtc_midnight.py suites/test_rtc_adjust.py suites/test_rtc_validity.py "
              "suites/test_rtc_drift.py")
PID_SUITES = "suites/test_pid.py suites/test_pid_control.py"
PYTEST = "{python} -m pytest -x -q -p no:cacheprovider "
#: the scheduling judge of the FBs models (see the docstring): after their suites, only if those pass
FAST_FORWARD = PYTEST + "tests/test_fast_forward.py"


def _in_turn(*commands: str) -> str:
    """One test command running ``commands`` in turn, each only if those before it passed."""
    return "sh -c " + shlex.quote(" && ".join(commands))


#: session → (the mutated file, the suites that judge it: every suite that can see the model; FUN86 reads the
#: temperatures, so the temperature model is judged by the PID suites too)
SESSIONS = {
    "rtc": (MODELS + "rtc.py", _in_turn(PYTEST + RTC_SUITES, FAST_FORWARD)),
    # (and the temperature suite again on CI's other temperature profile — 8 modules of the other kinds, °F, the fast
    # rate, 4-sample averaging: tests/test_temperature_suites.py's mixed_profile —, where averaging and the fast
    # rate's resolution run at all; the default profile has neither)
    # (and once more on the default profile with 2-sample averaging at the normal rate — 0.1 ° resolution with
    # averaging: averaged-temperature.toml)
    # (and in bench timing, where the model reads its table once per cycle and refreshes each module at its phase:
    # bench-timed.toml)
    "temperature": ([MODELS + "temperature.py", MODELS + "temperature_readings.py"], _in_turn(
        PYTEST + "suites/test_temperature.py " + PID_SUITES,
        *(PYTEST + f"suites/test_temperature.py --bench {profile}.toml"
          for profile in ("mixed-temperature", "averaged-temperature", "bench-timed")),
        FAST_FORWARD)),
    "fun86": ([MODELS + f"fun86{part}.py" for part in ("", "_law", "_pwm", "_alarms")],
              _in_turn(PYTEST + PID_SUITES, FAST_FORWARD)),
    # (and once more as a CR40, a CPU without a clock: cr40.toml)
    "s7": ("hil/families/s7smart/sim/clock.py", _in_turn(
        PYTEST + "suites/s7smart --bench fixtures/benches/s7-200smart.toml",
        PYTEST + "suites/s7smart --bench cr40.toml")),
}
#: the sample is drawn per group (in this order), over the group's mutants sorted by file, operator, occurrence
GROUPS = {"fbs": ("rtc", "temperature", "fun86"), "s7": ("s7",)}
SURVIVORS = ROOT / "benchmarks" / "mutation-survivors.toml"
KINDS = ("equivalent", "choice", "not_observable", "gap")
QUICK = 100
SEED = 26  # the sample is fixed: the same mutants every run of the same code (issue 26)


def _copy_tree(dest: Path) -> None:
    """The working tree as it is (uncommitted edits included), without caches, venvs and reports."""
    ignore = shutil.ignore_patterns(".git", ".venv", "__pycache__", "reports", "mutants", "*.sqlite", ".hypothesis")
    shutil.copytree(ROOT, dest, symlinks=True, ignore=ignore)


def _mixed_profile(dest: Path) -> None:
    sys.path.insert(0, str(ROOT))
    from tests.conftest import EMULATOR_BENCH
    from tests.test_temperature_suites import mixed_profile
    dest.write_text(mixed_profile(EMULATOR_BENCH.read_text(encoding="utf-8")), encoding="utf-8")


def _averaged_profile(dest: Path) -> None:
    """The emulator's profile with 2-sample averaging at the normal rate (0.1 ° resolution): averaging where the
    resolution check can see its arithmetic (the mixed profile averages at the fast rate's 1 °)."""
    text = (ROOT / "fixtures" / "benches" / "emulator.toml").read_text(encoding="utf-8")
    out = text.replace("averaging = 1\n", "averaging = 2\n", 1)
    assert out != text and 'rate = "normal"' in out
    dest.write_text(out, encoding="utf-8")


def _bench_timed_profile(dest: Path) -> None:
    """The emulator's profile in bench timing (hil.sim.timing), seed 1, scans of 5-20 ms: the schedule a bench may
    keep, which the instant profiles never run."""
    text = (ROOT / "fixtures" / "benches" / "emulator.toml").read_text(encoding="utf-8")
    out = text.replace("\nseed = 0\n", '\nseed = 1\ntiming = "bench"\nscan_time_range = [5, 20]\n', 1)
    assert out != text
    dest.write_text(out, encoding="utf-8")


def _cr40_profile(dest: Path) -> None:
    """The S7-200 SMART profile as a CR40: a CPU without a real-time clock."""
    text = (ROOT / "fixtures" / "benches" / "s7-200smart.toml").read_text(encoding="utf-8")
    out = text.replace('cpu = "ST40"', 'cpu = "CR40"', 1)
    assert out != text
    dest.write_text(out, encoding="utf-8")


def _config(work: Path, name: str, timeout: float) -> Path:
    module, command = SESSIONS[name]
    path = work / f"cosmic-ray-{name}.toml"
    path.write_text(
        "[cosmic-ray]\n"
        f"module-path = {json.dumps(module)}\n"
        f"timeout = {timeout}\n"
        "excluded-modules = []\n"
        f"test-command = {json.dumps(command.format(python=sys.executable))}\n\n"
        "[cosmic-ray.distributor]\nname = \"local\"\n", encoding="utf-8")
    return path


def _cosmic_ray(work: Path, *args: str) -> None:
    exe = Path(sys.executable).with_name("cosmic-ray")
    if not exe.exists():
        sys.exit(f"mutation testing needs cosmic-ray beside this Python ({exe} is missing): "
                 f"{sys.executable} -m pip install cosmic-ray==8.7")
    env = {**os.environ, "PYTHONPATH": str(work), "HIL_STATE_DIR": str(work / ".hil-state"),
           "HIL_LOCK_DIR": str(work / ".hil-locks")}
    subprocess.run([str(exe), "--verbosity", "WARNING", *args], cwd=work, env=env, check=True)


def _key(item) -> tuple:
    m = item.mutations[0]
    return str(m.module_path), m.operator_name, m.occurrence


def _sample(db_paths: list[Path], keep: int | None, rng: random.Random) -> int:
    """Mark all but ``keep`` of the sessions' mutants together (a fixed random sample) as skipped; how many are left."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult
    items = []
    for path in db_paths:
        with use_db(str(path), WorkDB.Mode.open) as db:
            items += [(path, w) for w in db.work_items]
    items.sort(key=lambda pw: _key(pw[1]))
    if keep is None or keep >= len(items):
        return len(items)
    chosen = {w.job_id for _, w in rng.sample(items, keep)}
    for path in db_paths:
        with use_db(str(path), WorkDB.Mode.open) as db:
            db.set_multiple_results([w.job_id for p, w in items if p == path and w.job_id not in chosen],
                                    WorkResult(worker_outcome=WorkerOutcome.SKIPPED))
    return keep


def _results(db_path: Path, work: Path) -> list[dict]:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome
    rows = []
    with use_db(str(db_path), WorkDB.Mode.open) as db:
        for item, result in db.completed_work_items:
            if result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            spec = item.mutations[0]
            lines = (work / spec.module_path).read_text(encoding="utf-8").splitlines()
            rows.append({
                "file": str(spec.module_path), "operator": spec.operator_name.removeprefix("core/"),
                "occurrence": spec.occurrence, "line": spec.start_pos[0],
                "source": lines[spec.start_pos[0] - 1].strip(), "function": spec.definition_name or "",
                "worker": result.worker_outcome.value,
                "outcome": result.test_outcome.value if result.test_outcome is not None else "",
                "timeout": result.output == "timeout",  # cosmic-ray counts a suite that hangs as killed
                "diff": result.diff or "",
            })
    return rows


def _classifications() -> list[dict]:
    if not SURVIVORS.is_file():
        return []
    entries = tomllib.loads(SURVIVORS.read_text(encoding="utf-8")).get("survivor", [])
    for e in entries:
        if e.get("kind") not in KINDS or not e.get("reason"):
            raise SystemExit(f"{SURVIVORS}: {e}: kind must be one of {KINDS}, with a reason")
    return entries


def _classify(row: dict, entries: list[dict]) -> dict | None:
    for e in entries:
        if e["file"] == row["file"] and e["operator"] == row["operator"] and e["source"] == row["source"]:
            return e
    return None


def run(sample: int | None, timeout: float, keep_work: bool) -> int:
    started = time.monotonic()
    out_dir = ROOT / "reports" / "mutation"
    out_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="hil-mutation-"))
    try:
        _copy_tree(work / "tree")
        tree = work / "tree"
        _mixed_profile(tree / "mixed-temperature.toml")
        _averaged_profile(tree / "averaged-temperature.toml")
        _cr40_profile(tree / "cr40.toml")
        _bench_timed_profile(tree / "bench-timed.toml")
        rng = random.Random(SEED)
        rows: list[dict] = []
        dbs = {}
        for name in SESSIONS:
            config = _config(tree, name, timeout)
            db = tree / f"session-{name}.sqlite"
            _cosmic_ray(tree, "init", str(config), str(db))
            # the unmutated tree must pass, or every mutant would count as killed
            _cosmic_ray(tree, "baseline", str(config))
            dbs[name] = (config, db)
        totals = {name: _count(db) for name, (_, db) in dbs.items()}
        everything = sum(totals.values())
        for group, names in GROUPS.items():  # the sample is split over the groups in proportion to their mutants
            size = sum(totals[n] for n in names)
            share = None if sample is None else max(1, round(sample * size / everything))
            left = _sample([dbs[n][1] for n in names], share, rng)
            print(f"{group}: {left} of {size} mutants to run", flush=True)
        for config, db in dbs.values():
            _cosmic_ray(tree, "exec", str(config), str(db))
            rows += _results(db, tree)
        seconds = time.monotonic() - started
        (work / "run.json").write_text(json.dumps({"totals": totals, "sample": sample, "seconds": seconds}))
        return _report(rows, totals, sample, seconds, out_dir)
    finally:
        if keep_work:
            print(f"scratch copy kept: {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)


def _count(db_path: Path) -> int:
    from cosmic_ray.work_db import WorkDB, use_db
    with use_db(str(db_path), WorkDB.Mode.open) as db:
        return db.num_work_items


def _report(rows: list[dict], totals: dict[str, int], sample: int | None, seconds: float, out_dir: Path) -> int:
    entries = _classifications()
    killed = [r for r in rows if r["outcome"] == "killed"]
    survived = [r for r in rows if r["outcome"] == "survived"]
    incompetent = [r for r in rows if r["outcome"] not in ("killed", "survived")]
    kinds: Counter = Counter()
    lines = ["# Surviving mutants", "", f"{len(rows)} mutants run ({'all' if sample is None else f'sample of {sample}'}"
             f", seed {SEED}) of {sum(totals.values())}; {len(killed)} killed, {len(survived)} survived, "
             f"{len(incompetent)} incompetent (the mutant does not even import / run)", ""]
    for r in survived:
        entry = _classify(r, entries)
        kind = entry["kind"] if entry else "unclassified"
        kinds[kind] += 1
        lines += [f"## {r['file']}:{r['line']} {r['operator']} ({r['function']}) — {kind}", "",
                  f"{entry['reason'] if entry else 'NOT CLASSIFIED: add it to benchmarks/mutation-survivors.toml'}",
                  "", "```diff", r["diff"].strip(), "```", ""]
    judged = len(killed) + len(survived) - kinds["equivalent"]
    score = 100.0 * len(killed) / judged if judged else 100.0
    # and of what a bench could show at all (without the [our choice] and the not-observable survivors)
    showable = judged - kinds["choice"] - kinds["not_observable"]
    observable_score = 100.0 * len(killed) / showable if showable else 100.0
    summary = {"tool": "cosmic-ray 8.7", "sample": sample, "seed": SEED, "mutants_total": totals, "run": len(rows),
               "killed": len(killed), "survived": len(survived), "incompetent": len(incompetent),
               "survivors_by_kind": dict(kinds), "score_percent": round(score, 1),
               "score_observable_percent": round(observable_score, 1), "seconds": round(seconds)}
    (out_dir / "score.json").write_text(json.dumps({**summary, "mutants": rows}, indent=1), encoding="utf-8")
    (out_dir / "survivors.md").write_text("\n".join(lines), encoding="utf-8")
    print(json.dumps(summary))
    print(f"mutation score: {score:.1f} % (killed / non-equivalent mutants run); {observable_score:.1f} % of those a "
          f"bench could show (without [our choice] and not-observable survivors); report in {out_dir}")
    if kinds["unclassified"]:
        print(f"{kinds['unclassified']} surviving mutants are not classified yet (see {out_dir / 'survivors.md'})")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help=f"a fixed sample of {QUICK} mutants (≤ 10 min)")
    parser.add_argument("--sample", type=int, metavar="N", help="a fixed sample of N mutants")
    parser.add_argument("--timeout", type=float, default=45.0,
                        help="seconds per mutant's suite run (default 45; the suites take ≈ 5)")
    parser.add_argument("--keep", action="store_true", help="keep the scratch copy (the cosmic-ray sessions)")
    parser.add_argument("--report-from", metavar="DIR", type=Path,
                        help="only write the report again from a kept scratch copy (after classifying survivors)")
    parser.add_argument("--record", action="store_true",
                        help="also write the score (reports/mutation/score.json's summary) to docs/figures/"
                             "mutation-sample-N.json, which the documentation site shows (docs/_ext/hil_docs.py): "
                             "figures never typed by hand; alone, records the last run's")
    args = parser.parse_args()
    sample = QUICK if args.quick else args.sample
    if args.report_from is not None:
        done = report_again(args.report_from)
    elif sample is not None or not args.record:
        done = run(sample, args.timeout, args.keep)
    else:
        done = 0
    if args.record and done == 0:
        print(f"recorded in {record_last_score()}")
    return done


def record_last_score() -> Path:
    """The last run's summary (without its per-mutant rows), stamped, as docs/figures/mutation-sample-N.json (or
    mutation-all.json for every mutant)."""
    summary = json.loads((ROOT / "reports" / "mutation" / "score.json").read_text(encoding="utf-8"))
    summary.pop("mutants", None)
    name = "mutation-all" if summary["sample"] is None else f"mutation-sample-{summary['sample']}"
    return record_figure(summary, name)


def report_again(work: Path) -> int:
    tree = work / "tree"
    meta = json.loads((work / "run.json").read_text(encoding="utf-8"))
    rows = [row for name in SESSIONS for row in _results(tree / f"session-{name}.sqlite", tree)]
    return _report(rows, meta["totals"], meta["sample"], meta["seconds"], ROOT / "reports" / "mutation")


if __name__ == "__main__":
    sys.exit(main())
