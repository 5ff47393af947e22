"""``hil history``: the runs the store kept — list, show, compare, trend, yield, flaky, export, sync.

Rich tables on a terminal; in a pipe, tab-separated lines with a header (``cut``, ``awk`` and spreadsheets read
them).  The store: ``--url``, else ``$HIL_HISTORY_URL``, else the ``--profile``'s ``[history] url``, else SQLite in
hil's state directory (hil.history.config), as the run that recorded them.
"""

from __future__ import annotations

import argparse
import csv
import datetime as dt
import io
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from hil.bench.profile import load_profile
from hil.cli.parser import Subparsers
from hil.core.errors import InvalidValue
from hil.core.redact import hide_password
from hil.history import config
from hil.history.analysis import compare, first_pass_yield, flaky, trend_figure
from hil.history.store import Store, reaching
from hil.history.sync import sync


# -- the store ------------------------------------------------------------------------------------------------------
def _store(args: argparse.Namespace) -> Any:
    profile_url = None
    if args.profile:
        profile_url = load_profile(args.profile).history_url
    url = config.resolve(args.url, profile_url)
    if url is None:
        raise InvalidValue("the history is off ($HIL_HISTORY_URL or [history] url = 'off') — give --url")
    with reaching(url):
        return Store(url)


def _date(text: str | None, what: str) -> dt.datetime | None:
    if text is None:
        return None
    try:
        return dt.datetime.fromisoformat(text.strip())
    except ValueError:
        raise InvalidValue(f"{what} {text!r} — write YYYY-MM-DD or YYYY-MM-DD HH:MM (UTC)") from None


def _filters(args: argparse.Namespace) -> dict[str, Any]:
    return {"bench": args.bench, "plc": args.plc, "verdict": args.verdict, "since": _date(args.since, "--since"),
            "until": _date(args.until, "--until")}


# -- output -------------------------------------------------------------------------------------------------------
def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, dt.datetime):
        return value.strftime("%Y-%m-%d %H:%M:%S")
    return str(value)


def _emit(console: Console, title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """A rich table on a terminal; tab-separated lines under a header in a pipe."""
    if console.is_terminal:
        table = Table(title=title, title_justify="left")
        for c in columns:
            table.add_column(c, overflow="fold")
        for r in rows:
            table.add_row(*(escape(_cell(v)) for v in r))
        console.print(table)
        return
    out = console.file  # not console.print: rich expands tabs
    out.write(f"# {title}\n")
    for line in [columns, *rows]:
        out.write("\t".join(_cell(v).replace("\t", " ").replace("\n", " ") for v in line) + "\n")
    out.flush()


def _change(a: dict[str, Any] | None, b: dict[str, Any] | None) -> str:
    """B − A of a measurement both runs have a value of, else nothing."""
    if a is None or b is None or a["value"] is None or b["value"] is None:
        return ""
    return f"{b['value'] - a['value']:+g}"


def _say(console: Console, text: str) -> None:
    console.print(text, highlight=False, soft_wrap=True, markup=False)


def _counts(counts: dict[str, int]) -> str:
    order = ("passed", "failed", "error", "skipped", "xfailed", "xpassed")
    return ", ".join(f"{counts[k]} {k}" for k in order if counts.get(k)) or "no tests"


def _state(run: dict[str, Any]) -> str:
    return run["verdict"] if run["finished"] else "NOT FINISHED"


# -- the actions ----------------------------------------------------------------------------------------------------
def history(args: argparse.Namespace, console: Console) -> int:
    store = _store(args)
    try:
        with reaching(store.url):  # a store that goes away while it is read: one line, as when it cannot be opened
            return ACTIONS[args.history_command](store, args, console)
    finally:
        store.close()


def _list(store: Any, args: argparse.Namespace, console: Console) -> int:
    found = store.runs(**_filters(args), limit=args.limit or None)
    _emit(console, f"runs in {store.shown}", ("run", "started (UTC)", "bench", "verdict", "tests", "PLC", "suites",
                                             "uuid"),
          [(r["id"], r["started_at"], r["bench"], _state(r), _counts(r["counts"]), r["plc"], r["suites_commit"],
            r["uuid"]) for r in found])
    return 0


def _show(store: Any, args: argparse.Namespace, console: Console) -> int:
    run = store.run(args.run)
    fields = ("uuid", "bench", "target", "transport", "plc", "rtc_chip", "profile", "profile_sha256", "suites_commit",
              "harness_version", "operator", "station", "lab_place", "host", "started_at", "ended_at", "stopped",
              "not_run", "plc_restored", "report")
    _emit(console, f"run {run['id']}: {_state(run)}", ("field", "value"),
          [(f, run[f]) for f in fields if run.get(f) not in (None, "")])
    notes = store.recoveries_of(run["id"])
    if notes:
        _emit(console, "recovery at its start", ("note",), [(n,) for n in notes])
    found = store.tests_of(run["id"])
    _emit(console, f"tests ({len(found)})", ("outcome", "test", "attempt", "s", "requirements", "message"),
          [(t["outcome"], t["nodeid"], t["attempt"], round(t["duration"] or 0, 3), t["requirements"],
            (t["message"] or "").splitlines()[-1][:160] if t["message"] else "") for t in found])
    values = [(t["nodeid"], m) for t in found for m in t["measurements"]]
    if values:
        _emit(console, f"measurements ({len(values)})", ("test", "measurement", "value", "unit", "low", "high",
                                                         "outcome"),
              [(n, m["name"], m["value"], m["unit"], m["low"], m["high"], m["outcome"]) for n, m in values])
    return 0


def _compare(store: Any, args: argparse.Namespace, console: Console) -> int:
    a, b = store.run(args.a), store.run(args.b)
    c = compare(a, store.tests_of(a["id"]), b, store.tests_of(b["id"]), tolerance=args.tolerance)
    _say(console, f"A = run {a['id']} ({a['bench']}, {_cell(a['started_at'])}, {_state(a)}); "
                  f"B = run {b['id']} ({b['bench']}, {_cell(b['started_at'])}, {_state(b)})")
    if c.identity:
        _emit(console, "what differs between the runs", ("field", "A", "B"), c.identity)
    else:
        _say(console, "same bench, PLC identity, profile, suites commit and harness version")
    _emit(console, f"tests that changed outcome ({len(c.tests)})", ("test", "A", "B"), c.tests)
    if c.only_a or c.only_b:
        _emit(console, "tests in one run only", ("test", "in"),
              [(t, "A only") for t in c.only_a] + [(t, "B only") for t in c.only_b])

    def side(m: dict[str, Any] | None) -> str:
        if m is None:
            return "—"
        if m["value"] is None:
            return "not measured (UNSET)"
        return f"{_cell(m['value'])}{' ' + m['unit'] if m['unit'] else ''} {m['outcome']}"
    _emit(console, f"measurements that moved ({len(c.measurements)})", ("test", "measurement", "A", "B", "change"),
          [(n, name, side(x), side(y), _change(x, y)) for n, name, x, y in c.measurements])
    return 0


def _trend(store: Any, args: argparse.Namespace, console: Console) -> int:
    rows = store.measurement_history(args.measurement, bench=args.bench, nodeid=args.test)
    if not rows:
        raise InvalidValue(f"no values of measurement {args.measurement!r} in {store.shown}"
                           + (f" for bench {args.bench!r}" if args.bench else "")
                           + ": `hil history show last` lists a run's measurements")
    _emit(console, f"{args.measurement}: {len(rows)} values", ("run", "started (UTC)", "bench", "PLC", "value", "unit",
                                                              "low", "high", "outcome", "test"),
          [(r["run_id"], r["started_at"], r["bench"], r["plc"], r["value"], r["unit"], r["low"], r["high"],
            r["outcome"], r["nodeid"]) for r in rows])
    if (args.plot or "").lower() == "none":
        return 0
    safe = "".join(ch if ch.isalnum() or ch in "._-" else "_" for ch in args.measurement)
    path = Path(args.plot or Path("reports") / f"trend-{safe}.png")
    path.parent.mkdir(parents=True, exist_ok=True)
    trend_figure(args.measurement, rows).savefig(path, format="png")
    _say(console, f"plot: {path}")
    return 0


def _yield(store: Any, args: argparse.Namespace, console: Console) -> int:
    tests, overall = first_pass_yield(store.test_history(bench=args.bench))
    _emit(console, "first-pass yield per test (lowest first)", ("test", "runs", "passed first time", "yield"),
          [(y.nodeid, y.runs, y.first_pass, f"{y.rate:.0%}") for y in tests])
    if overall.runs:
        _say(console, f"runs that passed every test first time: {overall.first_pass} of {overall.runs} "
                      f"({overall.rate:.0%})")
    return 0


def _flaky(store: Any, args: argparse.Namespace, console: Console) -> int:
    found = flaky(store.test_history(bench=args.bench))
    _emit(console, f"flaky tests ({len(found)}): outcome changed with the same bench, PLC identity and profile",
          ("test", "bench", "flips", "outcomes (oldest first)", "PLC", "profile"),
          [(f.nodeid, f.bench, f.flips, " ".join(o[0].upper() for o in f.outcomes), f.plc, f.profile_sha256[:12])
           for f in found])
    return 0


def _export(store: Any, args: argparse.Namespace, console: Console) -> int:
    found = store.runs(**_filters(args), newest_first=False)
    rows = _run_rows(found) if args.what == "runs" else _test_rows(store, found, measurements=args.what != "tests")
    text = _as_json(rows) if args.format == "json" else _as_csv(rows)
    if args.output:
        Path(args.output).write_text(text, encoding="utf-8")
        _say(console, f"{len(rows)} {args.what} written to {args.output}")
    else:
        sys.stdout.write(text)
    return 0


def _run_rows(found: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """A row per run, its test counts in one column."""
    return [{k: v for k, v in r.items() if k != "counts"} | {"tests": _counts(r["counts"])} for r in found]


def _test_rows(store: Any, found: list[dict[str, Any]], *, measurements: bool) -> list[dict[str, Any]]:
    """A row per test of each run (``measurements``: per measurement of each test), with its run's identity."""
    rows = []
    for r in found:
        run = {"run": r["id"], "run_uuid": r["uuid"], "started_at": r["started_at"], "bench": r["bench"],
               "plc": r["plc"]}
        for t in store.tests_of(r["id"]):
            if not measurements:
                rows.append(run | {k: v for k, v in t.items() if k not in ("measurements", "run_id")})
                continue
            rows += [run | {"nodeid": t["nodeid"]} | {k: v for k, v in m.items() if k not in ("test_id", "run_id")}
                     for m in t["measurements"]]
    return rows


def _as_json(rows: list[dict[str, Any]]) -> str:
    return json.dumps(rows, indent=1, default=_cell) + "\n"


def _as_csv(rows: list[dict[str, Any]]) -> str:
    """CSV with a header row (nothing at all for no rows: there are no columns to name)."""
    out = io.StringIO()
    if rows:
        writer = csv.DictWriter(out, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows({k: _cell(v) for k, v in row.items()} for row in rows)
    return out.getvalue()


def _sync(store: Any, args: argparse.Namespace, console: Console) -> int:
    spool_url = config.spool_url()
    if store.url == spool_url:
        raise InvalidValue("the store is the local spool itself — give --url (or $HIL_HISTORY_URL) of the store to "
                           "upload to")
    if not Path(spool_url.removeprefix("sqlite:///")).exists():
        _say(console, f"nothing to upload: no local spool ({hide_password(spool_url)})")
        return 0
    with reaching(spool_url):
        spool = Store(spool_url)
    try:
        done = sync(spool, store)
    finally:
        spool.close()
    _say(console, f"uploaded {done.runs} run{'s' if done.runs != 1 else ''} ({done.tests} tests) from "
                  f"{hide_password(spool_url)} to {store.shown}")
    return 0


ACTIONS = {"list": _list, "show": _show, "compare": _compare, "trend": _trend, "yield": _yield, "flaky": _flaky,
           "export": _export, "sync": _sync}


# -- the command line -----------------------------------------------------------------------------------------------
EPILOG = """examples:
  hil history list --bench emulator --verdict failed
  hil history show last
  hil history compare last~1 last           (tests that changed outcome, measurements that moved)
  hil history trend drift_uncompensated --bench emulator --plot drift.png
  hil history yield   |   hil history flaky
  hil history export --what measurements --format csv -o measurements.csv
  hil history sync                          (upload what was kept locally while the store was unreachable)
"""


def add_parser(sub: Subparsers, summary: str) -> None:
    parser = sub.add_parser("history", help=summary, epilog=EPILOG,
                            description="Every run is recorded (bench, PLC identity, profile hash, suites commit, "
                                        "each test and measurement) in SQLite in hil's state directory, or a "
                                        "lab's PostgreSQL server ([history] url, $HIL_HISTORY_URL).")
    parser.set_defaults(func=history)
    actions = parser.add_subparsers(dest="history_command", metavar="ACTION", required=True)

    def action(name: str, text: str) -> argparse.ArgumentParser:
        p = actions.add_parser(name, help=text)
        p.add_argument("--url", metavar="URL", help="the store (default $HIL_HISTORY_URL, else --profile's [history] "
                                                     "url, else SQLite in hil's state directory)")
        p.add_argument("--profile", metavar="FILE", help="a bench profile whose [history] url names the store")
        return p

    def filters(p: argparse.ArgumentParser) -> None:
        p.add_argument("--bench", metavar="NAME", help="runs of this bench ([bench] name)")
        p.add_argument("--plc", metavar="TEXT", help="runs of PLCs whose identity contains TEXT (e.g. an OS version)")
        p.add_argument("--verdict", metavar="V", help="PASSED, FAILED, INTERRUPTED …, or 'not finished'")
        p.add_argument("--since", metavar="DATE", help="runs started on or after DATE (YYYY-MM-DD[ HH:MM], UTC)")
        p.add_argument("--until", metavar="DATE", help="runs started before DATE")

    p = action("list", "the runs, newest first")
    filters(p)
    p.add_argument("--limit", type=int, default=50, metavar="N", help="at most N runs (default 50; 0: all)")
    p = action("show", "one run: identity, verdict, tests, measurements")
    p.add_argument("run", metavar="RUN", help="its number, UUID (or its start), last, or last~N")
    p = action("compare", "two runs: what differs in identity, the tests that changed outcome, measurements moved")
    p.add_argument("a", metavar="A", help="the run compared from (changes read B − A): its number, UUID (or its "
                                          "start), last, or last~N")
    p.add_argument("b", metavar="B", help="the run compared with, written as A")
    p.add_argument("--tolerance", type=float, default=None, metavar="REL",
                   help="measurements within this relative difference are not named (default: any difference the "
                        "reports show, at six significant digits)")
    p = action("trend", "one measurement over the runs: a table and a plot (value against date, with its limits)")
    p.add_argument("measurement", metavar="MEASUREMENT",
                   help="the measurement's name as the reports show it (e.g. drift_residual, pid_settle_time)")
    p.add_argument("--bench", metavar="NAME", help="this bench's runs only")
    p.add_argument("--test", metavar="NODEID", help="this test's measurement only (where several measure the name)")
    p.add_argument("--plot", metavar="PNG", help="where the plot goes (default reports/trend-MEASUREMENT.png; "
                                                 "'none': no plot)")
    p = action("yield", "first-pass yield per test: of the runs that decided it, how many passed it first time")
    p.add_argument("--bench", metavar="NAME", help="this bench's runs only")
    p = action("flaky", "tests whose outcome changed while the bench, the PLC's identity and the profile did not")
    p.add_argument("--bench", metavar="NAME", help="this bench's runs only")
    p = action("export", "runs, tests or measurements as CSV or JSON")
    filters(p)
    p.add_argument("--what", choices=("runs", "tests", "measurements"), default="runs",
                   help="a row per run (default), per test of each run, or per measurement of each test")
    p.add_argument("--format", choices=("csv", "json"), default="csv",
                   help="CSV with a header row (default) or a JSON array of objects")
    p.add_argument("-o", "--output", metavar="FILE", help="write here (default: standard output)")
    action("sync", "upload the runs kept in the local spool (while the store was unreachable) to the store")
