"""The rich side of the console: header panel, summary table by area, and a bar for long waits on a real bench.

Everything is rendered to a string and written through pytest's terminal reporter (see spec/pymodbus-notes.md,
"rich inside pytest"), so ``-q``, ``--color``, ``NO_COLOR`` and pipes behave as pytest's own output does: with no
markup (a pipe, CI, ``--color=no``) the text carries no control characters and boxes are plain ASCII.
"""

from __future__ import annotations

import contextlib
import io
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from rich import box
from rich.console import Console, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from hil.plugin.reporting.model import TestRecord, outcome_counts

OUTCOMES = ("passed", "failed", "error", "skipped", "xfailed", "xpassed")
_STYLE = {"passed": "green", "failed": "bold red", "error": "bold red", "skipped": "yellow", "xfailed": "yellow",
          "xpassed": "yellow"}


def shown_outcomes(counts: Counter) -> tuple[str, ...]:
    """The outcome columns of a summary: xfailed and xpassed only when there are such (as in pytest's summary)."""
    return tuple(o for o in OUTCOMES if o not in ("xfailed", "xpassed") or counts.get(o))


def plural(n: int, word: str) -> str:
    """``1 error``, ``2 errors``."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


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
    tally = _Tally.of(records)
    table = _areas_table(tally, color)
    return Group(table, _reasons_table(tally.skips, color)) if tally.skips else table


@dataclass
class _Tally:
    """What the summary counts: outcomes by area, skips by (area, reason), measurements by (area, kind)."""

    by_area: defaultdict[str, Counter[str]] = field(default_factory=lambda: defaultdict(Counter))
    skips: Counter[tuple[str, str]] = field(default_factory=Counter)
    measurements: Counter[tuple[str, str]] = field(default_factory=Counter)

    @classmethod
    def of(cls, records: Iterable[TestRecord]) -> _Tally:
        tally = cls()
        for r in records:
            tally.by_area[r.area].update(outcome_counts([r]))
            if r.outcome == "skipped":
                tally.skips[(r.area, r.message or "no reason given")] += 1
            for m in r.measurements:
                if m.value is not None:
                    tally.measurements[(r.area, "in limits" if m.passed else "out")] += 1
                elif r.outcome not in ("skipped", "xfailed"):  # a skipped test measures nothing: not a missing one
                    tally.measurements[(r.area, "not measured")] += 1
        return tally

    def measured(self, area: str | None = None) -> dict[str, int]:
        """Measurements by kind, in ``area`` (None: everywhere)."""
        out: Counter[str] = Counter()
        for (a, kind), n in self.measurements.items():
            if area is None or a == area:
                out[kind] += n
        return out


def _areas_table(tally: _Tally, color: bool) -> Table:
    """One row per area (its count of each outcome that occurs, its measurements), then the totals."""
    table = Table(title="hil results by area", box=_box(color), title_justify="left")
    table.add_column("area", no_wrap=True)
    outcomes = shown_outcomes(Counter(o for counts in tally.by_area.values() for o in counts.elements()))
    for outcome in outcomes:
        table.add_column(outcome, justify="right")
    table.add_column("measurements", justify="right")
    total: Counter[str] = Counter()
    for area in sorted(tally.by_area):
        counts = tally.by_area[area]
        total.update(counts)
        cells = [Text(str(counts.get(o, 0)), style=_STYLE[o] if (counts.get(o) and color) else "")
                 for o in outcomes]
        table.add_row(Text(area), *cells, _measured(tally.measured(area)))
    table.add_section()
    table.add_row("all", *(str(total.get(o, 0)) for o in outcomes), _measured(tally.measured()))
    return table


def _reasons_table(skips: Counter[tuple[str, str]], color: bool) -> Table:
    """Each distinct skip reason, by area, the commonest first."""
    reasons = Table(title="skip reasons", box=_box(color), title_justify="left")
    reasons.add_column("area", no_wrap=True)
    reasons.add_column("tests", justify="right")
    reasons.add_column("reason")
    for (area, why), n in sorted(skips.items(), key=lambda kv: (kv[0][0], -kv[1])):
        reasons.add_row(Text(area), str(n), Text(why))  # "[pid]" in a reason is the section to add, not markup
    return reasons


def _measured(counts: dict[str, int]) -> str:
    """``5 in limits, 1 out, 2 not measured`` (the kinds that occur; "in limits" always when any does)."""
    if not any(counts.values()):
        return ""
    return ", ".join(f"{counts.get(kind, 0)} {kind}" for kind in ("in limits", "out", "not measured")
                     if counts.get(kind) or kind == "in limits")


class WaitProgress:
    """A wait listener (:meth:`hil.core.timebase.HostTimebase.add_wait_listener`) for long waits on a real bench:
    on a terminal a transient bar (test name, time remaining); elsewhere (CI logs) one plain line when the wait
    starts and one every ``log_every`` seconds, so a long bench wait never looks like a hang.  Waits shorter than
    ``minimum`` seconds show nothing; virtual time never calls it."""

    def __init__(self, *, current: Callable[[], str], suspend: Callable[[], Any], minimum: float = 3.0,
                 log_every: float = 30.0) -> None:
        self.current = current
        self.suspend = suspend  # context manager: capture off, so the bar or line reaches the terminal
        self.minimum = minimum
        self.log_every = log_every
        self._stack: contextlib.ExitStack | None = None
        self._progress: Any = None
        self._task: Any = None
        self._console: Console | None = None
        self._started = self._logged = 0.0

    def __call__(self, done: float, total: float) -> None:
        if done == 0.0:
            self._start(total)
        elif self._stack is not None:
            self._update(done, total)
        if done >= total and self._stack is not None:
            self._stack.close()
            self._stack = self._progress = None

    def _start(self, total: float) -> None:
        if self._stack is not None:
            self._stack.close()
            self._stack = None
        if total < self.minimum:
            return
        import sys
        self._stack = contextlib.ExitStack()
        self._stack.enter_context(self.suspend())
        self._console = Console(file=sys.stdout, highlight=False)
        self._started = self._logged = time.monotonic()
        what = f"{self.current()} — bench.wait({total:g} s)"
        if self._console.is_terminal:
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
            self._console.print()  # leave pytest's progress line alone
            self._progress = self._stack.enter_context(Progress(
                TextColumn("{task.description}", style="cyan", markup=False), BarColumn(),
                TextColumn("{task.fields[left]}", markup=False), TimeRemainingColumn(), console=self._console,
                transient=True))
            self._task = self._progress.add_task(what, total=total, left="")
        else:
            self._line(f"\nhil: {what} started")

    def _update(self, done: float, total: float) -> None:
        now = time.monotonic()
        if self._progress is not None:
            self._progress.update(self._task, completed=done, left=f"{total - done:,.0f} s left "
                                                                   f"({now - self._started:,.0f} s so far)")
        elif now - self._logged >= self.log_every and done < total:
            self._logged = now
            self._line(f"hil: {self.current()} — bench.wait({total:g} s): {done:,.0f} s done, "
                       f"{total - done:,.0f} s left")

    def _line(self, text: str) -> None:
        assert self._console is not None
        self._console.print(Text(text), soft_wrap=True)
        self._console.file.flush()
