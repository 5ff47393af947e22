"""Report details a user reads: outcomes counted as pytest counts them, the suite named after the bench, the HTML
page's layout at 390, 800 and 1280 px (in headless Chromium when it is installed), its status filter and sections."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy  # noqa: F401 - pytester's in-process runs restore sys.modules, and numpy cannot load twice in a process

from hil.plugin.reporting.html import plot_figure, write_html, write_html_sections
from hil.plugin.reporting.model import Measurement, Series
from hil.plugin.reporting.model import TestRecord as Record
from tests.browser import look, needs_chromium

EMULATOR_BENCH = Path(__file__).resolve().parent.parent / "fixtures" / "benches" / "emulator.toml"

MIXED = """
import pytest

@pytest.fixture
def broken():
    raise RuntimeError("setup broke")

def test_passes(bench):
    bench.plc.io.read_words("R0", 1)

@pytest.mark.xfail(reason="known")
def test_xfails(bench):
    assert False

def test_skips(bench):
    pytest.skip("not here")

def test_errors(bench, broken):
    pass
"""


def test_xfail_error_grammar_and_suite_name(pytester) -> None:
    pytester.makepyfile(test_mixed=MIXED)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "--junitxml=out/junit.xml",
                                          "-o", "junit_family=xunit1", "--hil-html=out/report.html",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, xfailed=1, skipped=1, errors=1)
    table = next(i for i, line in enumerate(result.outlines) if "hil results by area" in line)
    header = result.outlines[table + 2]
    assert "xfailed" in header, result.outlines[table:table + 8]
    all_row = next(line for line in result.outlines[table:] if line.startswith("| all"))
    assert re.findall(r"\d+", all_row) == ["1", "0", "1", "1", "1"], all_row  # passed failed error skipped xfailed
    page = (pytester.path / "out" / "report.html").read_text()
    assert "1 error," in page and "1 errors" not in page and "1 skipped, 1 xfailed" in page
    root = ET.parse(pytester.path / "out" / "junit.xml").getroot()
    suite = root if root.tag == "testsuite" else root.find("testsuite")
    assert suite.get("name") == "emulator"  # the bench, not "pytest"
    names = {p.get("name") for p in suite.find("properties").iter("property")}
    assert {"hil.bench", "hil.target"} <= names


def _records() -> list[Record]:
    long_id = "suites/test_temperature.py::test_sensor_break_reads_28767_with_only_its_bit[" + "p" * 120 + "]"
    records = [Record(f"{long_id}{i}", "temperature", "passed", 0.01, requirements=["TEMP-SENS-1"]) for i in range(40)]
    records += [Record(f"suites/test_pid.py::test_alarm_{i}", "PID", "skipped", 0.0,
                       message="the bench profile has no [pid] section: " + "add it to the profile " * 12)
                for i in range(20)]
    trace = "# wire trace (calls): 5 entries\n" + "".join(f"10:00:00.000 == | read_words(R{i})\n" for i in range(5))
    records.append(Record("suites/test_rtc.py::test_fails", "RTC", "failed", 0.5, message="boom",
                          longrepr="E   " + "x" * 400, trace=trace))
    pid = Record("suites/test_pid_control.py::test_closed_loop", "PID", "passed", 2.0,
                 measurements=[Measurement("pid_settle_time", 120.0, "s", None, 600.0)])
    pid.series.append(Series.build("pid", [(t, 20 + t, 50, t % 100) for t in range(300)],
                                   columns=("t", "PV", "SV", "output"), secondary=("output",)))
    records.append(pid)
    return records


def test_html_layout_rules_filter_and_sections(tmp_path: Path) -> None:
    page = write_html(tmp_path / "r.html", _records(), [("hil.bench", "emulator")]).read_text()
    # long ids wrap inside the page (inline CSS)
    assert "table-layout:fixed" in page and "overflow-wrap:anywhere" in page
    assert '<div class="filters">' in page and 'value="passed"' in page and "hide-" in page
    assert page.count('<details class="section"') >= 3
    assert "wire trace (5 calls)" in page  # the in-process target records calls, not frames


def test_merged_html_has_a_section_per_bench(tmp_path: Path) -> None:
    a, b = _records()[:3], _records()[-2:]
    page = write_html_sections(tmp_path / "m.html", [("bench-a", a, [("hil.bench", "bench-a")]),
                                                     ("bench-b", b, [("hil.bench", "bench-b")])]).read_text()
    assert "<h2>bench bench-a — 3 tests" in page and "<h2>bench bench-b — 2 tests" in page
    assert "5 tests" in page


# a badge is one word on one line: one taller than the shortest has wrapped ("passe" / "d"); then the status filter
_REPORT_CHECKS = """
  const badges = [...document.querySelectorAll('.badge')].filter(e => e.offsetParent !== null);
  const line = Math.min(...badges.map(e => e.offsetHeight));
  const passed = () => [...document.querySelectorAll('.passed-row')].filter(e => e.offsetParent !== null).length;
  const before = passed();
  const box = document.querySelector('.filters input[value="passed"]');
  box.checked = false; box.dispatchEvent(new Event('change'));
  return {badges: badges.length, wrapped: badges.filter(e => e.offsetHeight > 1.5 * line).length,
          shown_before: before, shown_after: passed()};
"""


@needs_chromium
def test_html_fits_the_window_in_headless_chromium(tmp_path: Path) -> None:
    page = write_html(tmp_path / "r.html", _records(), [("hil.bench", "emulator")])
    for width, layout in look(page, extra_js=_REPORT_CHECKS).items():
        assert layout.fits, f"at {width} px the page is {layout.scroll_width} px wide: {layout.offenders}"
        checks = layout.extra
        assert checks["badges"] > 40 and checks["wrapped"] == 0, f"badges broken over two lines at {width} px: {checks}"
        assert checks["shown_before"] > 0 and checks["shown_after"] == 0  # the status filter hides the passed tests


def test_the_report_plots_legend_is_inside_the_picture_and_clear_of_the_axis_label() -> None:
    """The PID trace's legend sits below the axes (inside, it would cover the trace), whole and over no label."""
    series = next(r for r in _records() if r.series).series[0]
    fig = plot_figure(series)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legend = fig.axes[0].get_legend().get_window_extent(renderer)
    picture, label = fig.bbox, fig.axes[0].xaxis.label.get_window_extent(renderer)
    assert picture.x0 <= legend.x0 and legend.x1 <= picture.x1 and picture.y0 <= legend.y0, (legend, picture)
    assert not legend.overlaps(label), (legend, label)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["PV", "SV", "output"]


@needs_chromium
def test_the_layout_probe_names_what_runs_off_the_edge(tmp_path: Path) -> None:
    """The probe that passes the report finds an element wider than a phone, and lets a table scroll in its box."""
    page = tmp_path / "wide.html"
    page.write_text('<!DOCTYPE html><html><body><p>fits</p><div id="wide" style="width:600px">too wide</div>'
                    '<div style="overflow-x:auto"><table style="width:900px"><tr><td>scrolls in its box</td></tr>'
                    "</table></div></body></html>", encoding="utf-8")
    layouts = look(page)
    assert not layouts[390].fits and layouts[390].offenders == ["div#wide reaches 608 px"], layouts[390]
    assert layouts[800].fits and layouts[1280].offenders == [], layouts  # the table's box scrolls, the page does not


REPO = Path(__file__).resolve().parent.parent


def test_s7_buffer_parameters_have_readable_ids(pytester) -> None:
    result = pytester.runpytest_inprocess(str(REPO / "suites" / "s7smart" / "test_s7_rtc.py"), "--co", "-q",
                                          "--bench", str(REPO / "fixtures" / "benches" / "s7-200smart.toml"),
                                          "-p", "no:cacheprovider")
    ids = [line for line in result.outlines if "::test_set_then_read_round_trip[" in line]
    assert ids and ids[0].endswith("[24.06.15.08.30.00.00.07-7]"), ids
    assert not any("\\x" in line for line in result.outlines)


def test_pid_trace_is_an_attached_file_and_the_settle_time_one_measurement(pytester) -> None:
    result = pytester.runpytest_inprocess(str(REPO / "suites" / "test_pid_control.py"), "-k", "closed_loop",
                                          "--bench", str(EMULATOR_BENCH), "--junitxml=out/junit.xml",
                                          "-o", "junit_family=xunit1", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    case = next(ET.parse(pytester.path / "out" / "junit.xml").getroot().iter("testcase"))
    props = {p.get("name"): p.get("value") for p in case.iter("property")}
    assert "pid_trace_csv" not in props and "pid_settled_s" not in props
    assert "hil.measure.pid_settle_time" in props
    attached = Path(props["hil.attachment.pid_trace.csv"])
    assert attached.is_file() and attached.read_text().count("\n") > 10
