"""What ``hil history`` computes over the store: a comparison of two runs, a measurement's trend, first-pass yield
and flaky tests.  Pure functions over what :class:`hil.history.store.Store` returns."""

from __future__ import annotations

import math
import textwrap
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

#: the run fields a comparison names when they differ (what changed between the two runs besides the tests)
IDENTITY = ("bench", "target", "transport", "plc", "rtc_chip", "profile", "profile_sha256", "suites_commit",
            "harness_version", "operator", "station", "lab_place", "verdict")
DECIDED = ("passed", "failed", "error")  # outcomes that say something of the PLC (a skip says nothing)


@dataclass
class Comparison:
    a: dict[str, Any]
    b: dict[str, Any]
    identity: list[tuple[str, Any, Any]] = field(default_factory=list)  # (field, in A, in B)
    tests: list[tuple[str, str, str]] = field(default_factory=list)  # (nodeid, outcome in A, in B)
    only_a: list[str] = field(default_factory=list)
    only_b: list[str] = field(default_factory=list)
    #: (nodeid, name, A's measurement or None, B's or None): value or outcome differs, or measured in one only
    measurements: list[tuple[str, str, dict[str, Any] | None, dict[str, Any] | None]] = field(default_factory=list)


def _last_attempts(tests: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for t in tests:
        if t["nodeid"] not in out or t["attempt"] >= out[t["nodeid"]]["attempt"]:
            out[t["nodeid"]] = t
    return out


def _moved(a: float | None, b: float | None, tolerance: float | None) -> bool:
    """``tolerance`` None: moved when the reports show the two differently (``%g``, six significant digits, as
    JUnit and the HTML write them), so float noise below what any report shows is not a change."""
    if a is None or b is None:
        return (a is None) != (b is None)
    if tolerance is None or math.isnan(a) or math.isnan(b):
        return f"{a:g}" != f"{b:g}"
    return abs(a - b) > tolerance * max(abs(a), abs(b))


def compare(run_a: dict[str, Any], tests_a: list[dict[str, Any]], run_b: dict[str, Any],
            tests_b: list[dict[str, Any]], *, tolerance: float | None = None) -> Comparison:
    """``tolerance``: relative; a measurement whose values differ by no more is not named (None: a difference the
    reports show)."""
    out = Comparison(run_a, run_b)
    out.identity = [(k, run_a.get(k), run_b.get(k)) for k in IDENTITY if run_a.get(k) != run_b.get(k)]
    last_a, last_b = _last_attempts(tests_a), _last_attempts(tests_b)
    for nodeid in sorted(last_a.keys() | last_b.keys()):
        ta, tb = last_a.get(nodeid), last_b.get(nodeid)
        if ta is None:
            out.only_b.append(nodeid)
        elif tb is None:
            out.only_a.append(nodeid)
        elif ta["outcome"] != tb["outcome"]:
            out.tests.append((nodeid, ta["outcome"], tb["outcome"]))
        ma = {m["name"]: m for m in (ta or {}).get("measurements", [])}
        mb = {m["name"]: m for m in (tb or {}).get("measurements", [])}
        for name in sorted(ma.keys() | mb.keys()):
            x, y = ma.get(name), mb.get(name)
            if x is None or y is None or x["outcome"] != y["outcome"] or _moved(x["value"], y["value"], tolerance):
                out.measurements.append((nodeid, name, x, y))
    return out


@dataclass
class Flaky:
    bench: str
    plc: str
    profile_sha256: str
    nodeid: str
    outcomes: list[str]  # oldest first, every attempt
    flips: int


def flaky(history: list[dict[str, Any]], *, min_flips: int = 1) -> list[Flaky]:
    """Tests whose outcome changed between passed and failed/error while the bench, the PLC's identity and the
    profile stayed the same (a change of profile or PLC explains a change of outcome; it is not flakiness)."""
    groups: dict[tuple[str, str, str, str], list[str]] = defaultdict(list)
    for row in history:  # oldest first (Store.test_history)
        if row["outcome"] in DECIDED:
            groups[(row["bench"], row["plc"] or "", row["profile_sha256"] or "", row["nodeid"])].append(row["outcome"])
    found = []
    for (bench, plc, profile, nodeid), outcomes in groups.items():
        passed = [o == "passed" for o in outcomes]
        flips = sum(1 for x, y in zip(passed, passed[1:]) if x != y)
        if flips >= min_flips:
            found.append(Flaky(bench, plc, profile, nodeid, outcomes, flips))
    return sorted(found, key=lambda f: (-f.flips, f.bench, f.nodeid))


@dataclass
class Yield:
    nodeid: str
    runs: int  # runs that decided this test on its first attempt
    first_pass: int

    @property
    def rate(self) -> float:
        return self.first_pass / self.runs if self.runs else math.nan


def first_pass_yield(history: list[dict[str, Any]]) -> tuple[list[Yield], Yield]:
    """Per test: of the runs whose first attempt decided it (passed, failed or error), how many passed it first
    time; and over runs: of the runs that decided any test, how many passed every test first time."""
    per: dict[str, list[int]] = defaultdict(lambda: [0, 0])
    runs: dict[int, bool] = {}
    for row in history:
        if row["attempt"] != 1 or row["outcome"] not in DECIDED:
            continue
        good = row["outcome"] == "passed"
        per[row["nodeid"]][0] += 1
        per[row["nodeid"]][1] += good
        runs[row["run_id"]] = runs.get(row["run_id"], True) and good
    tests = [Yield(nodeid, n, p) for nodeid, (n, p) in sorted(per.items())]
    return sorted(tests, key=lambda y: (y.rate, y.nodeid)), Yield("every test", len(runs), sum(runs.values()))


def trend_series(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """A measurement's values grouped by PLC (and by test, where more than one test measures that name)."""
    tests = {r["nodeid"] for r in rows}
    out: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        key = f"{r['bench']}: {r['plc'] or 'PLC unknown'}"
        if len(tests) > 1:
            key += f" ({r['nodeid']})"
        out[key].append(r)
    return dict(out)


def trend_figure(name: str, rows: list[dict[str, Any]]) -> Any:
    """A matplotlib Figure (Agg canvas, no pyplot): value against date, one line per PLC, its limits dashed."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # constrained layout makes room for the legend below the axis label; a long label is wrapped, never cut
    fig = Figure(figsize=(9, 4), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    colors = ["#0969da", "#cf222e", "#1a7f37", "#8250df", "#bc4c00", "#57606a"]
    unit = next((r["unit"] for r in rows if r["unit"]), "")
    for i, (label, points) in enumerate(trend_series(rows).items()):
        color = colors[i % len(colors)]
        shown = [p for p in points if p["value"] is not None]
        ax.plot([p["started_at"] for p in shown], [p["value"] for p in shown], "-o", color=color, markersize=4,
                linewidth=1.3, label=textwrap.fill(label, 70))
        for limit in ("low", "high"):
            if any(p[limit] is not None for p in points):
                ax.step([p["started_at"] for p in points], [p[limit] for p in points], "--", where="post",
                        color=color, alpha=0.6, linewidth=1, label=f"{limit} limit")
    ax.set_title(f"{name} over runs", fontsize=11)
    ax.set_xlabel("run started (UTC)")
    ax.set_ylabel(f"{name}{f' ({unit})' if unit else ''}")
    ax.grid(True, alpha=0.3)
    fig.legend(loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    fig.autofmt_xdate()
    return fig
