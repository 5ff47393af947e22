"""The HTML report: one self-contained file (inline CSS, plots as base64 PNG), readable offline.

Plots are drawn by matplotlib on its Agg canvas (no pyplot, no global backend switch), so writing a report
never touches a display or the test process's matplotlib state.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
from collections import Counter, defaultdict
from pathlib import Path
from typing import Iterable

from hil.plugin.reporting.console import OUTCOMES
from hil.plugin.reporting.model import Series, TestRecord

MAX_TRACE_LINES = 400  # per test in the page; the full trace is in reports/traces/

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#1d2330;background:#fafbfc}
h1{margin:0 0 4px;font-size:24px} h2{margin-top:28px;border-bottom:1px solid #d8dee4;padding-bottom:4px}
.meta{color:#57606a;margin-bottom:16px}
table{border-collapse:collapse;margin:8px 0;background:#fff}
th,td{border:1px solid #d8dee4;padding:4px 10px;text-align:left;vertical-align:top;font-size:14px}
th{background:#f1f3f5}
td.n{text-align:right;font-variant-numeric:tabular-nums}
.badge{display:inline-block;padding:1px 8px;border-radius:10px;font-size:12px;font-weight:600;color:#fff}
.passed{background:#1a7f37}.failed,.error{background:#cf222e}.skipped{background:#9a6700}
.FAIL{color:#cf222e;font-weight:600}.PASS{color:#1a7f37;font-weight:600}
.test{background:#fff;border:1px solid #d8dee4;border-radius:6px;padding:10px 14px;margin:10px 0}
.test.failed,.test.error{border-left:5px solid #cf222e}.test.passed{border-left:5px solid #1a7f37}
.test.skipped{border-left:5px solid #9a6700}
.test h3{margin:0 0 6px;font-size:15px;font-family:ui-monospace,SFMono-Regular,Menlo,monospace;word-break:break-all}
pre{background:#f6f8fa;border:1px solid #d8dee4;padding:8px;overflow-x:auto;font-size:12px;white-space:pre-wrap}
img.plot{max-width:100%;border:1px solid #d8dee4;background:#fff;margin:6px 0}
details summary{cursor:pointer;color:#0969da}
.filters{margin:8px 0}
"""


def plot_png(series: Series) -> bytes:
    """The series as a PNG: each column against ``x``; ``secondary`` columns on a right-hand axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.6), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    xs = series.columns[series.x]
    right = ax.twinx() if series.secondary else None
    lines = []
    colors = ["#0969da", "#cf222e", "#1a7f37", "#8250df", "#bc4c00", "#57606a"]
    for i, (name, ys) in enumerate((c, v) for c, v in series.columns.items() if c != series.x):
        target = right if name in series.secondary else ax
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
    ax.legend(lines, [ln.get_label() for ln in lines], loc="best", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _summary(records: list[TestRecord]) -> str:
    by_area: dict[str, Counter] = defaultdict(Counter)
    skips: dict[str, Counter] = defaultdict(Counter)
    for r in records:
        by_area[r.area][r.outcome] += 1
        if r.outcome == "skipped":
            skips[r.area][r.message or "no reason given"] += 1
    rows = []
    total: Counter = Counter()
    for area in sorted(by_area):
        total.update(by_area[area])
        reasons = "<br>".join(_e(f"{n}× {why}" if n > 1 else why) for why, n in skips[area].most_common())
        cells = "".join(f'<td class="n">{by_area[area].get(o, 0)}</td>' for o in OUTCOMES)
        rows.append(f"<tr><td>{_e(area)}</td>{cells}<td>{reasons}</td></tr>")
    cells = "".join(f'<td class="n"><b>{total.get(o, 0)}</b></td>' for o in OUTCOMES)
    rows.append(f"<tr><td><b>all</b></td>{cells}<td></td></tr>")
    head = "".join(f"<th>{o}</th>" for o in OUTCOMES)
    return f"<table><tr><th>area</th>{head}<th>skip reasons</th></tr>{''.join(rows)}</table>"


def _test(record: TestRecord) -> str:
    parts = [f'<div class="test {record.outcome}" id="{_e(record.nodeid)}">',
             f'<h3><span class="badge {record.outcome}">{record.outcome}</span> {_e(record.nodeid)}</h3>',
             f'<div class="meta">area {_e(record.area)} · {record.duration:.3f} s</div>']
    if record.measurements:
        rows = "".join(
            f"<tr><td>{_e(m.name)}</td><td class='n'>{m.value:g}</td><td>{_e(m.unit)}</td>"
            f"<td class='n'>{'' if m.low is None else f'{m.low:g}'}</td>"
            f"<td class='n'>{'' if m.high is None else f'{m.high:g}'}</td>"
            f"<td class='{m.outcome}'>{m.outcome}</td></tr>" for m in record.measurements)
        parts.append("<table><tr><th>measurement</th><th>value</th><th>unit</th><th>low</th><th>high</th>"
                     f"<th>outcome</th></tr>{rows}</table>")
    if record.outcome in ("failed", "error") and (record.longrepr or record.message):
        parts.append(f"<pre>{_e(record.longrepr or record.message)}</pre>")
    elif record.outcome == "skipped" and record.message:
        parts.append(f"<div>skipped: {_e(record.message)}</div>")
    for series in record.series:
        try:
            data = base64.b64encode(plot_png(series)).decode("ascii")
            parts.append(f'<img class="plot" alt="{_e(series.title)}" src="data:image/png;base64,{data}">')
        except Exception as exc:  # noqa: BLE001 - a broken plot must not lose the report
            parts.append(f"<div>plot {_e(series.name)} could not be drawn: {_e(exc)}</div>")
    if record.trace:
        lines = record.trace.splitlines()
        shown = "\n".join(lines[:MAX_TRACE_LINES])
        more = (f"\n… {len(lines) - MAX_TRACE_LINES} more lines in {record.trace_file}"
                if len(lines) > MAX_TRACE_LINES else "")
        where = f" — {_e(record.trace_file)}" if record.trace_file else ""
        parts.append(f"<details{' open' if record.outcome in ('failed', 'error') else ''}><summary>wire trace "
                     f"({len(lines) - 1} frames){where}</summary><pre>{_e(shown + more)}</pre></details>")
    parts.append("</div>")
    return "\n".join(parts)


def write_html(path: Path, records: Iterable[TestRecord], properties: list[tuple[str, str]], *,
               title: str = "hil test report") -> Path:
    records = list(records)
    counts = Counter(r.outcome for r in records)
    verdict = "FAILED" if counts.get("failed") or counts.get("error") else "PASSED"
    props = "".join(f"<tr><th>{_e(k.removeprefix('hil.'))}</th><td>{_e(v)}</td></tr>" for k, v in properties)
    order = {"failed": 0, "error": 0, "passed": 1, "skipped": 2}
    ranked = sorted(records, key=lambda r: (order.get(r.outcome, 3), not r.series, r.nodeid))
    detailed = [r for r in ranked if r.outcome in ("failed", "error") or r.measurements or r.series or r.trace]
    plain = [r for r in ranked if r not in detailed]
    tests = "\n".join(_test(r) for r in detailed)
    if plain:
        rows = "".join(f'<tr><td><span class="badge {r.outcome}">{r.outcome}</span></td><td>{_e(r.area)}</td>'
                       f'<td><code>{_e(r.nodeid)}</code></td><td class="n">{r.duration:.3f}</td>'
                       f'<td>{_e(r.message if r.outcome == "skipped" else "")}</td></tr>' for r in plain)
        tests += ("\n<h2>Other tests</h2>\n<table><tr><th>outcome</th><th>area</th><th>test</th><th>s</th>"
                  f"<th>skip reason</th></tr>{rows}</table>")
    now = dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M:%S %Z")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><style>{_CSS}</style></head>
<body>
<h1>{_e(title)} — <span class="badge {'passed' if verdict == 'PASSED' else 'failed'}">{verdict}</span></h1>
<div class="meta">generated {_e(now)} · {len(records)} tests · {counts.get('passed', 0)} passed,
{counts.get('failed', 0)} failed, {counts.get('error', 0)} errors, {counts.get('skipped', 0)} skipped</div>
<h2>Bench and PLC</h2>
<table>{props or '<tr><td>no bench was used</td></tr>'}</table>
<h2>Summary by area</h2>
{_summary(records)}
<h2>Tests</h2>
{tests or '<p>no tests ran</p>'}
</body></html>
"""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path
