"""The ``hil history`` sub-command's arguments (apart from its commands, hil.cli.history: building the parser of
every ``hil`` command must not import the store's SQLAlchemy)."""

from __future__ import annotations

import argparse

EPILOG = """examples:
  hil history list --bench emulator --verdict failed
  hil history show last
  hil history compare last~1 last           (tests that changed outcome, measurements that moved)
  hil history trend drift_uncompensated --bench emulator --plot drift.png
  hil history yield   |   hil history flaky
  hil history export --what measurements --format csv -o measurements.csv
  hil history sync                          (upload what was kept locally while the store was unreachable)
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    raw = argparse.RawDescriptionHelpFormatter
    history = sub.add_parser("history", help="the runs recorded so far: list, compare, trend, yield, flaky, export",
                             formatter_class=raw, epilog=EPILOG,
                             description="Every run is recorded (bench, PLC identity, profile hash, suites commit, "
                                         "each test and measurement) in SQLite in hil's state directory, or a "
                                         "lab's PostgreSQL server ([history] url, $HIL_HISTORY_URL).")
    actions = history.add_subparsers(dest="history_command", metavar="ACTION", required=True)

    def action(name: str, text: str) -> argparse.ArgumentParser:
        p = actions.add_parser(name, help=text, formatter_class=raw)
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
