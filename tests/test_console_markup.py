"""Square brackets in what rich prints are text, not markup: a skip reason naming the "[pid]" section a user must
add, a bench named ``ext[pid]``, a test id with parameters — through the real console paths."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import pytest
from rich.console import Console

from hil.cli.many import BenchRun, print_summary
from hil.core.timebase import HostTimebase
from hil.plugin.reporting.console import WaitProgress, header_panel, render, summary_table
from hil.plugin.reporting.model import TestRecord as Record

EMULATOR_BENCH = Path(__file__).resolve().parent.parent / "fixtures" / "benches" / "emulator.toml"
REASON = "the bench profile has no [pid] section: add one"


@pytest.mark.parametrize("color", [True, False])
def test_skip_reason_and_area_keep_their_brackets(color: bool) -> None:
    records = [Record("suites/test_pid.py::test_x", "PID", "skipped", message=REASON),
               Record("suites/test_ext[pid].py::test_y", "ext[pid]", "passed")]
    text = render(summary_table(records, color=color), color=color, width=200)
    assert REASON in text and "ext[pid]" in text


def test_header_panel_keeps_a_bench_name_with_brackets() -> None:
    text = render(header_panel([("bench", "ext[pid] (benches/ext.toml)"), ("[key]", "v")], color=True),
                  color=True, width=120)
    assert "ext[pid]" in text and "[key]" in text


def test_the_wait_bar_shows_a_parametrised_test_id(monkeypatch, capsys) -> None:
    monkeypatch.setenv("FORCE_COLOR", "1")  # the bar draws on a terminal only
    monkeypatch.setenv("TTY_COMPATIBLE", "1")
    timebase = HostTimebase()
    timebase.add_wait_listener(WaitProgress(current=lambda: "suites/test_pid.py::test_alarm[pid]",
                                            suspend=contextlib.nullcontext, minimum=0.0))
    timebase.wait(0.6)
    out = capsys.readouterr().out
    assert "test_alarm[pid]" in out


def test_long_waits_print_a_line_every_so_often_when_not_on_a_terminal(monkeypatch, capsys) -> None:
    """CI logs (no terminal) see a plain line when a long bench wait starts and every ``log_every`` seconds."""
    monkeypatch.delenv("FORCE_COLOR", raising=False)
    monkeypatch.delenv("TTY_COMPATIBLE", raising=False)
    timebase = HostTimebase()
    timebase.add_wait_listener(WaitProgress(current=lambda: "suites/test_rtc_drift.py::test_day[pid]",
                                            suspend=contextlib.nullcontext, minimum=0.5, log_every=0.3))
    pieces: list[float] = []
    timebase.add_wait_listener(lambda done, total: pieces.append(done) if total == 1.0 else None)
    started = time.monotonic()
    timebase.wait(1.0)
    assert pieces == [0.0, 0.25, 0.5, 0.75, 1.0]  # the same wait, in pieces (counted, not timed)…
    # …each slept on the host, so the whole is not cut short: a guaranteed lower bound (time.sleep never returns
    # early; a busy host only makes the wait longer; the 1e-6 is the float clock's rounding)
    assert time.monotonic() - started >= 1.0 - 1e-6
    timebase.wait(0.2)  # under the minimum: nothing
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("hil: ")]
    assert lines[0] == "hil: suites/test_rtc_drift.py::test_day[pid] — bench.wait(1 s) started"
    # then a line at a piece's end (before the last) once log_every = 0.3 s of host time has passed since the last
    # line: at least one (0.5 s were slept by the second piece's end), at most one per piece (3) — a slow host can
    # only add lines up to that, never take one away
    assert 2 <= len(lines) <= 4 and "s left" in lines[1] and "\x1b" not in "".join(lines), lines


def test_many_benches_summary_keeps_bench_names(tmp_path: Path) -> None:
    console = Console(record=True, width=200, force_terminal=True)
    print_summary(console, [BenchRun("ext[pid]", "p.toml", tmp_path / "junit-ext[pid].xml", tmp_path / "run.log",
                                exit=0)], "reports/junit[all].xml")
    text = console.export_text()
    assert "ext[pid]" in text and "junit[all].xml" in text


def test_a_skip_reason_with_brackets_reaches_the_terminal(pytester) -> None:
    pytester.makepyfile(test_markup=f"""
        import pytest
        def test_needs_pid(bench):
            pytest.skip({REASON!r})
    """)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-p", "no:cacheprovider", "-rs")
    result.assert_outcomes(skipped=1)
    summary = "\n".join(line for line in result.outlines if "|" in line)
    assert "no [pid] section" in summary, result.stdout.str()
