"""What the HTML report shows of the bench's history: beside each measurement its last values on this bench (an
inline SVG sparkline, the limits as a band), a header line "since the last run on this bench: N tests changed
outcome", and a link to that run's report.  The reporter calls :meth:`Annotations.header` and
:meth:`Annotations.beside` while it writes the page (hil.plugin.reporting.html)."""

from __future__ import annotations

import html
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar
from urllib.parse import quote

from hil.core.measurement import Measurement


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


@dataclass
class Annotations:
    label: str  # the column's heading
    header_html: str
    series: dict[tuple[str, str], list[float | None]] = field(default_factory=dict)  # (nodeid, name) → oldest first

    @classmethod
    def build(cls, last: dict[str, Any] | None, values: list[dict[str, Any]], records: Iterable[Any], *,
              html: Path | None, store: str, spooled: bool = False) -> Annotations:
        records = list(records)
        series: dict[tuple[str, str], list[float | None]] = {}
        for v in values:
            series.setdefault((v["nodeid"], v["name"]), []).append(v["value"])
        runs = len({v["run_id"] for v in values})
        where = f"history: {_e(store)}" + (" (the local spool: the store was unreachable)" if spooled else "")
        if last is None:
            header = f"first run recorded on this bench · {where}"
        else:
            changed = sorted(r.nodeid for r in records
                             if r.nodeid in last["outcomes"] and last["outcomes"][r.nodeid] != r.outcome)
            when = last["started_at"].strftime("%Y-%m-%d %H:%M") + " UTC"
            state = last["verdict"] if last["finished"] else "did not finish"
            n = len(changed)
            line = (f"since the last run on this bench (#{last['id']}, {when}, {_e(state)}): "
                    f"{n} test{'s' if n != 1 else ''} changed outcome")
            if changed:
                items = "".join(f"<li><code>{_e(c)}</code>: {_e(last['outcomes'][c])} → "
                                f"{_e(next(r.outcome for r in records if r.nodeid == c))}</li>" for c in changed)
                line = f"<details><summary>{line}</summary><ul>{items}</ul></details>"
            header = f"{line} · {_previous_link(last, html)} · {where}"
        label = f"last {runs} run{'s' if runs != 1 else ''} on this bench" if runs else "earlier runs"
        return cls(label, header, series)

    def header(self) -> str:
        return f'<div class="meta history">{self.header_html}</div>'

    def beside(self, nodeid: str, m: Measurement) -> str:
        earlier = self.series.get((nodeid, m.name), [])
        return sparkline([*earlier, m.value], m.low, m.high) if earlier else "<span class='meta'>—</span>"


def _previous_link(last: dict[str, Any], page: Path | None) -> str:
    report = last.get("report") or ""
    if not report:
        return "its report was not kept"
    target = Path(report)
    if not target.is_file():
        return f"its report ({_e(target.name)}) is not on this host" if last["finished"] else \
            "its report was never finished"
    try:
        href = Path(os.path.relpath(target.resolve(), (page.parent if page else Path.cwd()).resolve())).as_posix()
    except ValueError:
        href = target.resolve().as_uri()
    return f'<a href="{_e(quote(href))}">previous report</a>'


def sparkline(values: list[float | None], low: float | None, high: float | None, *, width: int = 120,
              height: int = 22) -> str:
    """An inline SVG: the values oldest to newest (the newest, this run's, as a dot), the limits as a band."""
    # a run that measured nothing keeps its place and breaks the line: no value is drawn where none was read
    measured = {i: v for i, v in enumerate(values) if v is not None and not math.isnan(v)}
    if not measured:
        return "<span class='meta'>—</span>"
    plot = _Plot(width, height, *_value_range([*measured.values(), *(x for x in (low, high) if x is not None)]),
                 step=(width - 2 * _Plot.pad) / max(1, len(values) - 1))
    parts = [_band(plot, low, high)] if low is not None or high is not None else []
    for run in _stretches(sorted(measured)):
        points = " ".join(f"{plot.x(i)},{plot.y(measured[i])}" for i in run)
        parts.append(f'<polyline fill="none" stroke="#0969da" stroke-width="1.3" points="{points}"/>')
    newest = len(values) - 1
    if newest in measured:  # this run's dot; none when this run measured nothing (the title says "—")
        parts.append(_dot(plot, newest, measured[newest], low, high))
    title = " → ".join("—" if v is None else f"{v:g}" for v in values)
    return (f'<svg class="spark" width="{width}" height="{height}" viewBox="0 0 {width} {height}" role="img">'
            f"<title>{_e(title)}</title>{''.join(parts)}</svg>")


def _band(plot: _Plot, low: float | None, high: float | None) -> str:
    """The limits as a green band (one open side reaches the box's edge)."""
    top, bottom = plot.y(high if high is not None else plot.hi), plot.y(low if low is not None else plot.lo)
    return (f'<rect x="0" y="{top}" width="{plot.width}" height="{max(0.5, bottom - top)}" fill="#1a7f37" '
            f'fill-opacity="0.12"/>')


def _dot(plot: _Plot, index: int, value: float, low: float | None, high: float | None) -> str:
    """This run's value: green within its limits, red outside."""
    inside = (low is None or value >= low) and (high is None or value <= high)
    return f'<circle cx="{plot.x(index)}" cy="{plot.y(value)}" r="2.5" fill="{"#1a7f37" if inside else "#cf222e"}"/>'


def _value_range(bounds: list[float]) -> tuple[float, float]:
    """The values' range, widened around a value that does not change (a flat line, not float noise blown up)."""
    lo, hi = min(bounds), max(bounds)
    if hi - lo <= 1e-9 * max(abs(lo), abs(hi)):
        half = max(abs(lo), 1.0) * 0.1
        lo, hi = lo - half, hi + half
    return lo, hi


@dataclass(frozen=True)
class _Plot:
    """Where a value and a run's index go in the sparkline's box (SVG y grows downwards)."""
    width: int
    height: int
    lo: float
    hi: float
    step: float
    pad: ClassVar[int] = 3

    def x(self, index: int) -> float:
        return round(self.pad + index * self.step, 1)

    def y(self, value: float) -> float:
        return round(self.pad + (self.height - 2 * self.pad) * (1 - (value - self.lo) / (self.hi - self.lo)), 1)


def _stretches(indexes: list[int]) -> list[list[int]]:
    """Sorted ``indexes`` cut where one is missing: [0, 1, 3, 4] → [[0, 1], [3, 4]]."""
    out: list[list[int]] = []
    for i in indexes:
        if out and out[-1][-1] == i - 1:
            out[-1].append(i)
        else:
            out.append([i])
    return out
