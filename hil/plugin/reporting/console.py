"""The rich side of the console: header panel, summary table by area, and a bar for long waits on a real bench.

Everything is rendered to a string and written through pytest's terminal reporter (see spec/pymodbus-notes.md,
"rich inside pytest"), so ``-q``, ``--color``, ``NO_COLOR`` and pipes behave as pytest's own output does: with no
markup (a pipe, CI, ``--color=no``) the text carries no control characters and boxes are plain ASCII.
"""

from __future__ import annotations

import io
import time
from collections import Counter, defaultdict
from typing import Any, Callable, Iterable

from rich import box
from rich.console import Console, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from hil.plugin.reporting.model import TestRecord

OUTCOMES = ("passed", "failed", "error", "skipped")
_STYLE = {"passed": "green", "failed": "bold red", "error": "bold red", "skipped": "yellow"}


def render(renderable: RenderableType, *, color: bool, width: int) -> str:
    """``renderable`` as text: ANSI styles only when ``color`` (pytest's ``hasmarkup``)."""
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=color, color_system="standard" if color else None,
                      no_color=not color, width=max(width, 60), highlight=False, emoji=False,
                      legacy_windows=False, soft_wrap=False)
    console.print(renderable)
    return buf.getvalue()


def _box(color: bool) -> box.Box:
    return box.ROUNDED if color else box.ASCII


def header_panel(items: Iterable[tuple[str, str]], *, color: bool, title: str = "hil bench") -> Panel:
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold cyan" if color else "", no_wrap=True)
    grid.add_column()
    for key, value in items:
        grid.add_row(Text(str(key)), Text(str(value)))  # Text: "[pid]" in a name or message is not markup
    return Panel(grid, title=title, title_align="left", box=_box(color), expand=False)


def summary_table(records: Iterable[TestRecord], *, color: bool) -> RenderableType:
    """Pass/fail/skip counts and measurements by area, then each distinct skip reason with its count."""
    from rich.console import Group
    by_area: dict[str, Counter] = defaultdict(Counter)
    skips: Counter = Counter()
    measurements: Counter = Counter()
    for r in records:
        by_area[r.area][r.outcome] += 1
        if r.outcome == "skipped":
            skips[(r.area, r.message or "no reason given")] += 1
        for m in r.measurements:
            measurements[(r.area, m.passed)] += 1
    table = Table(title="hil results by area", box=_box(color), title_justify="left")
    table.add_column("area", no_wrap=True)
    for outcome in OUTCOMES:
        table.add_column(outcome, justify="right")
    table.add_column("measurements", justify="right")
    total: Counter = Counter()
    for area in sorted(by_area):
        counts = by_area[area]
        total.update(counts)
        cells = [Text(str(counts.get(o, 0)), style=_STYLE[o] if (counts.get(o) and color) else "")
                 for o in OUTCOMES]
        ok, bad = measurements[(area, True)], measurements[(area, False)]
        shown = "" if not (ok or bad) else f"{ok} in limits" + (f", {bad} out" if bad else "")
        table.add_row(Text(area), *cells, shown)
    table.add_section()
    ok, bad = sum(n for (a, p), n in measurements.items() if p), sum(n for (a, p), n in measurements.items() if not p)
    table.add_row("all", *(str(total.get(o, 0)) for o in OUTCOMES),
                  "" if not (ok or bad) else f"{ok} in limits" + (f", {bad} out" if bad else ""))
    if not skips:
        return table
    reasons = Table(title="skip reasons", box=_box(color), title_justify="left")
    reasons.add_column("area", no_wrap=True)
    reasons.add_column("tests", justify="right")
    reasons.add_column("reason")
    for (area, why), n in sorted(skips.items(), key=lambda kv: (kv[0][0], -kv[1])):
        reasons.add_row(Text(area), str(n), Text(why))  # "[pid]" in a reason is the section to add, not markup
    return Group(table, reasons)


class WaitProgress:
    """Replaces a real bench's ``wait``: the same sleep, with a transient bar (test name, time remaining).

    Only on a terminal, only for waits of at least ``minimum`` seconds; never in virtual time."""

    def __init__(self, wait: Callable[[float], None], *, current: Callable[[], str],
                 suspend: Callable[[], Any], minimum: float = 3.0) -> None:
        self.wait = wait
        self.current = current
        self.suspend = suspend  # context manager: capture off, so the bar reaches the terminal
        self.minimum = minimum

    def __call__(self, seconds: float) -> None:
        if seconds < self.minimum:
            self.wait(seconds)
            return
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
        import sys
        with self.suspend():
            console = Console(file=sys.stdout)
            if not console.is_terminal:
                self.wait(seconds)
                return
            console.print()  # leave pytest's progress line alone
            with Progress(TextColumn("{task.description}", style="cyan", markup=False), BarColumn(),
                          TextColumn("{task.fields[left]}", markup=False),
                          TimeRemainingColumn(), console=console, transient=True) as progress:
                task = progress.add_task(f"{self.current()} — bench.wait({seconds:g} s)", total=seconds, left="")
                done = 0.0
                step = max(0.25, seconds / 400)
                started = time.monotonic()
                while done < seconds:
                    chunk = min(step, seconds - done)
                    self.wait(chunk)
                    done += chunk
                    progress.update(task, completed=done, left=f"{seconds - done:,.0f} s left "
                                                               f"({time.monotonic() - started:,.0f} s so far)")
