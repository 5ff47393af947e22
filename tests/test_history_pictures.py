"""The history's pictures: the report's sparkline (a run that measured nothing is a gap, never a point the line
passes through) and `hil history trend --plot` (its legend whole, clear of the axis label)."""

from __future__ import annotations

import re

from hil.history.annotate import sparkline


def _lines(svg: str) -> list[list[tuple[float, float]]]:
    return [[tuple(map(float, p.split(","))) for p in m.split()] for m in re.findall(r'points="([^"]*)"', svg)]


def test_an_unset_value_breaks_the_line_and_keeps_its_place():
    svg = sparkline([1.0, 2.0, None, 3.0, 4.0], 0.0, 5.0)
    lines = _lines(svg)
    assert len(lines) == 2 and [len(line) for line in lines] == [2, 2]  # no segment from 2.0 across to 3.0
    xs = [x for line in lines for x, _ in line]
    assert xs[2] - xs[1] > 1.5 * (xs[1] - xs[0])  # the unset run's slot stays empty between them
    assert "1 → 2 → — → 3 → 4" in svg


def test_no_dot_for_this_run_when_it_measured_nothing():
    svg = sparkline([1.0, 2.0, None], 0.0, 1.5)
    assert "<circle" not in svg and "#cf222e" not in svg  # the previous run's 2.0 is not shown as this run's
    assert "<circle" in sparkline([1.0, 2.0], 0.0, 1.5)


def test_the_trend_plots_legend_is_whole_and_clear_of_the_axis_label():
    """Two PLCs whose labels are long (a test id beside each): every legend entry inside the picture, none over
    the x axis's label."""
    import datetime as dt

    from hil.history.analysis import trend_figure

    start = dt.datetime(2026, 12, 1, 8, 0)
    nodeids = ["suites/test_rtc_drift.py::test_drift_of_the_uncompensated_clock_is_within_the_crystals_tolerance",
               "suites/test_rtc_drift.py::test_d4054_compensates_the_measured_drift_to_within_the_residual_limit"]
    rows = [{"started_at": start + dt.timedelta(days=i), "value": 0.01 * i, "unit": "s/day", "low": -0.1,
             "high": 0.1, "bench": f"line-{n}-bench", "plc": f"FBs-24MC serial 00{n}", "nodeid": nodeids[n]}
            for i in range(4) for n in range(2)]
    fig = trend_figure("drift_residual", rows)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    picture = fig.bbox
    shown = (fig.legends or [fig.axes[0].get_legend()])[0]
    legend = shown.get_window_extent(renderer)
    label = fig.axes[0].xaxis.label.get_window_extent(renderer)
    assert picture.x0 <= legend.x0 and legend.x1 <= picture.x1 and picture.y0 <= legend.y0, (legend, picture)
    assert not legend.overlaps(label), (legend, label)
    texts = [t.get_text().replace("\n", "") for t in shown.get_texts()]
    assert all(any(n in t for t in texts) for n in nodeids), texts  # wrapped, not cut
