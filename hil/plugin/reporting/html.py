"""The HTML report: one self-contained file (inline CSS, plots as base64 PNG), readable offline.

Plots are drawn by matplotlib on its Agg canvas (no pyplot, no global backend switch), so writing a report
never touches a display or the test process's matplotlib state.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
import os
import re
from collections import Counter, defaultdict
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import quote

from hil.plugin.reporting.console import plural, shown_outcomes
from hil.plugin.reporting.model import Series, TestRecord, outcome_counts
from hil.plugin.reporting.requirements import requirements_section
from hil.plugin.reporting.verdict import INCOMPLETE, Verdict

if TYPE_CHECKING:  # matplotlib loads when a plot is drawn, not when a report module is imported
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

MAX_TRACE_LINES = 400  # per test in the page; the full trace is in reports/traces/

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#1d2330;background:#fafbfc}
h1{margin:0 0 4px;font-size:24px} h2{margin-top:28px;border-bottom:1px solid #d8dee4;padding-bottom:4px}
.meta{color:#57606a;margin-bottom:16px}
table{border-collapse:collapse;margin:8px 0;background:#fff;max-width:100%}
table.other{table-layout:fixed;width:100%;min-width:36em} table.other col.o{width:7em} table.other col.a{width:8em}
table.other col.s{width:5em} table.other col.t{width:45%}
table.other td code{overflow-wrap:anywhere}
td{overflow-wrap:anywhere}
th,td{border:1px solid #d8dee4;padding:4px 10px;text-align:left;vertical-align:top;font-size:14px}
th{background:#f1f3f5}
td.n{text-align:right;font-variant-numeric:tabular-nums}
.scroll{overflow-x:auto;max-width:100%}
.badge{display:inline-block;white-space:nowrap;padding:1px 8px;border-radius:10px;font-size:12px;font-weight:600;
color:#fff}
.passed{background:#1a7f37}.failed,.error{background:#cf222e}.skipped,.xfailed{background:#9a6700}
.aborted,.incomplete{background:#6639ba}
.FAIL{color:#cf222e;font-weight:600}.PASS{color:#1a7f37;font-weight:600}.UNSET{color:#9a6700;font-weight:600}
.test{background:#fff;border:1px solid #d8dee4;border-radius:6px;padding:10px 14px;margin:10px 0}
.test.failed,.test.error{border-left:5px solid #cf222e}.test.passed{border-left:5px solid #1a7f37}
.test.skipped,.test.xfailed{border-left:5px solid #9a6700}
.test.aborted,.test.incomplete{border-left:5px solid #6639ba}
details.section>summary{list-style:none} details.section>summary :is(h2,h3){display:inline-block;margin:8px 0}
details.section>summary::before{content:"▸ ";color:#57606a} details.section[open]>summary::before{content:"▾ "}
.test>summary{list-style:none}
.filters label{margin-right:14px;font-size:14px;cursor:pointer}
body.hide-passed .passed-row,body.hide-failed .failed-row,body.hide-error .error-row,
body.hide-skipped .skipped-row,body.hide-xfailed .xfailed-row,body.hide-failed .aborted-row,
body.hide-failed .incomplete-row{display:none}
.test h3{margin:0 0 6px;font-size:15px;font-family:ui-monospace,SFMono-Regular,Menlo,monospace;overflow-wrap:anywhere}
.verdict{font-weight:600;margin-bottom:8px}.verdict.bad{color:#cf222e}
pre{background:#f6f8fa;border:1px solid #d8dee4;padding:8px;overflow-x:auto;font-size:12px;white-space:pre-wrap}
img.plot{max-width:100%;border:1px solid #d8dee4;background:#fff;margin:6px 0}
details summary{cursor:pointer;color:#0969da}
.filters{margin:8px 0;position:sticky;top:0;background:#fafbfc;padding:6px 0;z-index:1}
@media (max-width:600px){body{margin:10px}}
"""


def plot_figure(series: Series) -> Figure:
    """The series drawn: each column against ``x``; ``secondary`` columns on a right-hand axis; the legend below
    the axes, inside the picture."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.6), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    xs = series.columns[series.x]
    right = ax.twinx() if series.secondary else None
    lines: list[Line2D] = []
    colors = ["#0969da", "#cf222e", "#1a7f37", "#8250df", "#bc4c00", "#57606a"]
    for i, (name, ys) in enumerate((c, v) for c, v in series.columns.items() if c != series.x):
        target = right if right is not None and name in series.secondary else ax
        style = "--" if target is right else "-"
        marker = "o" if len(xs) <= 40 else None
        lines += target.plot(xs, ys, style, color=colors[i % len(colors)], marker=marker, markersize=3,
                             linewidth=1.4, label=name)
    ax.set_xlabel(series.xlabel)
    ax.set_ylabel(series.ylabel)
    if right is not None:
        right.set_ylabel(series.secondary_label)
    ax.set_title(series.title, fontsize=11)
    ax.grid(True, alpha=0.3)
    # below the axes: a legend inside covers the data (a PID trace fills the whole box)
    ax.legend(handles=lines, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=max(1, len(lines)), fontsize=8,
              frameon=False)
    fig.tight_layout()
    return fig


def plot_png(series: Series) -> bytes:
    """The series as a PNG (:func:`plot_figure`)."""
    buf = io.BytesIO()
    plot_figure(series).savefig(buf, format="png")
    return buf.getvalue()


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _id(nodeid: str) -> str:
    """A test id that wraps where it reads (after / :: . _ - [ ,), not in the middle of a word."""
    return "<wbr>".join(_e(part) for part in re.split(r"(?<=[/:._\-\[,])", nodeid))


def _link(attached: str, base: Path) -> str:
    """An attachment's link relative to the report, so an archived copy of the reports directory keeps it."""
    target = Path(attached).resolve()
    try:
        href = quote(Path(os.path.relpath(target, base.resolve())).as_posix())
    except ValueError:  # another drive (Windows): no relative path exists
        href = target.as_uri()
    return f'<a href="{_e(href)}">{_e(target.name)}</a>'


def _summary(records: list[TestRecord]) -> str:
    outcomes = shown_outcomes(outcome_counts(records))
    by_area: dict[str, Counter] = defaultdict(Counter)
    skips: dict[str, Counter] = defaultdict(Counter)
    for r in records:
        by_area[r.area].update(outcome_counts([r]))
        if r.outcome == "skipped":
            skips[r.area][r.message or "no reason given"] += 1
    rows = []
    total: Counter = Counter()
    for area in sorted(by_area):
        total.update(by_area[area])
        reasons = "<br>".join(_e(f"{n}× {why}" if n > 1 else why) for why, n in skips[area].most_common())
        cells = "".join(f'<td class="n">{by_area[area].get(o, 0)}</td>' for o in outcomes)
        rows.append(f"<tr><td>{_e(area)}</td>{cells}<td>{reasons}</td></tr>")
    cells = "".join(f'<td class="n"><b>{total.get(o, 0)}</b></td>' for o in outcomes)
    rows.append(f"<tr><td><b>all</b></td>{cells}<td></td></tr>")
    head = "".join(f"<th>{o}</th>" for o in outcomes)
    return _scrolling(f"<table><tr><th>area</th>{head}<th>skip reasons</th></tr>{''.join(rows)}</table>")


def _test(record: TestRecord, base: Path, history: Any = None) -> str:
    """One test's card: its heading, then whatever it left — measurements, the failure or skip reason, plots,
    attachments, the wire trace."""
    opened = " open" if record.outcome.bad or record.series else ""
    parts = [f'<details class="test {record.outcome} {record.outcome}-row" id="{_e(record.nodeid)}"{opened}>',
             f'<summary><h3 style="display:inline"><span class="badge {record.outcome}">{record.outcome}</span> '
             f'{_id(record.nodeid)}</h3></summary>',
             f'<div class="meta">area {_e(record.area)} · {record.duration:.3f} s</div>',
             _measurements(record, history), _why(record), *(_plot(series) for series in record.series),
             *(f"<div>attached: {_link(attached, base)}</div>" for attached in record.attachments),
             _trace(record), "</details>"]
    return "\n".join(part for part in parts if part)


def _number(value: float | None) -> str:
    return "" if value is None else f"{value:g}"


def _measurements(record: TestRecord, history: Any) -> str:
    """The test's measurements with their limits and outcome; beside each, its history
    (:class:`hil.history.annotate.Annotations`) when the bench has earlier runs."""
    if not record.measurements:
        return ""
    rows = "".join(
        f"<tr><td>{_e(m.name)}</td><td class='n'>{_number(m.value) or '—'}</td><td>{_e(m.unit)}</td>"
        f"<td class='n'>{_number(m.low)}</td><td class='n'>{_number(m.high)}</td>"
        f"<td class='{m.outcome}'>{m.outcome}</td>"
        + (f"<td>{history.beside(record.nodeid, m)}</td>" if history is not None else "") + "</tr>"
        for m in record.measurements)
    more = f"<th>{_e(history.label)}</th>" if history is not None else ""
    return _scrolling("<table><tr><th>measurement</th><th>value</th><th>unit</th><th>low</th><th>high</th>"
                      f"<th>outcome</th>{more}</tr>{rows}</table>")


def _why(record: TestRecord) -> str:
    """What a failed test reported (its traceback), or why it was skipped or expected to fail."""
    if record.outcome.bad and (record.longrepr or record.message):
        return f"<pre>{_e(record.longrepr or record.message)}</pre>"
    if record.outcome in ("skipped", "xfailed") and record.message:
        return f"<div>{record.outcome}: {_e(record.message)}</div>"
    return ""


def _plot(series: Series) -> str:
    try:
        data = base64.b64encode(plot_png(series)).decode("ascii")
    except Exception as exc:  # noqa: BLE001 - a broken plot must not lose the report
        return f"<div>plot {_e(series.name)} could not be drawn: {_e(exc)}</div>"
    return f'<img class="plot" alt="{_e(series.title)}" src="data:image/png;base64,{data}">'


def _trace(record: TestRecord) -> str:
    """The wire trace's first lines, open when the test went wrong; the whole trace is in ``record.trace_file``."""
    if not record.trace:
        return ""
    lines = record.trace.splitlines()
    shown = "\n".join(lines[:MAX_TRACE_LINES])
    more = (f"\n… {len(lines) - MAX_TRACE_LINES} more lines in {record.trace_file}"
            if len(lines) > MAX_TRACE_LINES else "")
    where = f" — {_e(record.trace_file)}" if record.trace_file else ""
    unit = "call" if "(calls)" in lines[0] else "frame"  # the in-process target records calls, not frames
    return (f"<details{' open' if record.outcome.bad else ''}><summary>wire trace "
            f"({plural(len(lines) - 1, unit)}){where}</summary><pre>{_e(shown + more)}</pre></details>")


def _section(records: list[TestRecord], properties: list[tuple[str, str]], base: Path, history: Any = None) -> str:
    """Bench properties, the summary by area, and the tests of one bench."""
    props = "".join(f"<tr><th>{_e(k.removeprefix('hil.'))}</th><td>{_e(v)}</td></tr>" for k, v in properties)
    order = {"failed": 0, "error": 0, "aborted": 0, "incomplete": 0, "passed": 1, "skipped": 2, "xfailed": 2}
    ranked = sorted(records, key=lambda r: (order.get(r.outcome, 3), not r.series, r.nodeid))
    detailed = [r for r in ranked if r.outcome.bad or r.measurements or r.series or r.trace]
    plain = [r for r in ranked if r not in detailed]
    tests = "\n".join(_test(r, base, history) for r in detailed)
    if plain:
        rows = "".join(f'<tr class="{r.outcome}-row"><td><span class="badge {r.outcome}">{r.outcome}</span></td>'
                       f'<td>{_e(r.area)}</td><td><code>{_id(r.nodeid)}</code></td>'
                       f'<td class="n">{r.duration:.3f}</td>'
                       f'<td>{_e(r.message if r.outcome in ("skipped", "xfailed") else "")}</td></tr>' for r in plain)
        tests += _collapsible("Other tests", _scrolling(
            '<table class="other"><colgroup><col class="o"><col class="a"><col class="t"><col class="s"><col>'
            f'</colgroup><tr><th>outcome</th><th>area</th><th>test</th><th>s</th><th>reason</th></tr>{rows}</table>'),
            level=3)
    bench = _scrolling(f"<table>{props or '<tr><td>no bench was used</td></tr>'}</table>")
    return (_collapsible("Bench and PLC", bench)
            + _collapsible("Summary by area", _summary(records))
            + (_collapsible("Requirements", _scrolling(table)) if (table := requirements_section(records)) else "")
            + _collapsible("Tests", tests or "<p>no tests ran</p>"))


def _scrolling(table: str) -> str:
    """A table in a box of its own that scrolls sideways when the window is narrower than the table (a phone),
    so the page itself never does."""
    return f'<div class="scroll">{table}</div>'


def _collapsible(title: str, body: str, *, level: int = 2, opened: bool = True) -> str:
    return (f'<details class="section"{" open" if opened else ""}><summary><h{level}>{_e(title)}</h{level}>'
            f"</summary>\n{body}\n</details>\n")


_FILTER_JS = """
for (const box of document.querySelectorAll('.filters input')) {
  box.addEventListener('change', () => document.body.classList.toggle('hide-' + box.value, !box.checked));
}
"""


def _counts_line(records: list[TestRecord]) -> str:
    """``3 tests · 1 passed, 1 failed, 1 error, 0 skipped``: pytest's counts (a failed call and a failed teardown
    are one of each)."""
    counts = outcome_counts(records)
    parts = [f"{counts.get('passed', 0)} passed", f"{counts.get('failed', 0)} failed",
             plural(counts.get("error", 0), "error"), f"{counts.get('skipped', 0)} skipped"]
    parts += [f"{counts[o]} {o}" for o in ("xfailed", "xpassed") if counts.get(o)]
    return f"{plural(len(records), 'test')} · " + ", ".join(parts)


def write_html(path: Path, records: Iterable[TestRecord], properties: list[tuple[str, str]], *,
               title: str = "hil test report", verdict: Verdict | None = None, history: Any = None) -> Path:
    """One bench's report; ``verdict``: the run's (:mod:`hil.plugin.reporting.verdict`, from pytest's exit status);
    ``history``: the bench's earlier runs (:class:`hil.history.annotate.Annotations`), or None."""
    return write_html_sections(path, [("", list(records), properties)], title=title, verdict=verdict,
                               history=history)


def write_html_sections(path: Path, sections: list[tuple[str, list[TestRecord], list[tuple[str, str]]]], *,
                        title: str = "hil test report", verdict: Verdict | None = None, history: Any = None) -> Path:
    """One page; with several benches (``hil run --bench a --bench b``) one collapsible section per bench.

    The badge is ``verdict``'s; without one (a page made outside a session) it is read from the records."""
    everything = [r for _, records, _ in sections for r in records]
    counts = Counter(str(r.outcome) for r in everything)
    if verdict is None:
        verdict = Verdict("FAILED" if any(r.outcome.bad for r in everything) else "PASSED")
    if len(sections) == 1 and not sections[0][0]:
        body = _section(sections[0][1], sections[0][2], path.parent, history)
    else:
        body = "".join(f'<details class="section bench" open><summary><h2>bench {_e(name)} — '
                       f"{_e(_counts_line(records))}</h2></summary>\n{_section(records, props, path.parent)}"
                       f"</details>\n" for name, records, props in sections)
    badge = "passed" if verdict.passed else "skipped" if verdict.status == INCOMPLETE else "failed"
    said = verdict.line().partition(" — ")[2]
    said = f'<div class="verdict{"" if verdict.passed else " bad"}">{_e(said)}</div>' if said else ""
    filters = "".join(f'<label><input type="checkbox" value="{o}" checked> {o} ({counts.get(o, 0)})</label>'
                      for o in shown_outcomes(counts))
    now = dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M:%S %Z")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><style>{_CSS}</style></head>
<body>
<h1>{_e(title)} — <span class="badge {badge}">{_e(verdict.status)}</span></h1>
{said}<div class="meta">generated {_e(now)} · {_e(_counts_line(everything))}</div>{history.header() if history else ""}
<div class="filters">show: {filters}</div>
{body}
<script>{_FILTER_JS}</script>
</body></html>
"""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path
