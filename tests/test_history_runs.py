"""The run history of emulator runs (SQLite): four sessions of the drift suite and a test made to flip, then what
``hil history`` says of them — compare, trend, flaky, first-pass yield, export — and what each HTML report shows of
the runs before it."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.history_runs import bench_profile, history, pytest_run

DRIFT_TEST = "suites/test_rtc_drift.py::test_drift_measured_compensated_and_remeasured"
FLIP = REPO / "tests" / "data" / "history" / "flip_on_purpose.py"
FLIP_TEST = "tests/data/history/flip_on_purpose.py::test_flip"
#: (profile's [rtc] crystal_ppm, the flip test's outcome): the same profile twice (the flip test flips), then another
#: profile on the same bench, with a crystal too fast for D4054 to compensate (the drift test fails)
RUNS = [("39.12", "pass"), ("39.12", "fail"), ("300.0", "pass")]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    where = tmp_path_factory.mktemp("history-runs")
    url = f"sqlite:///{where / 'history.sqlite'}"
    junits = []
    for n, (ppm, outcome) in enumerate(RUNS):
        profile = bench_profile(where, "drift-bench", file=f"profile-{ppm}.toml",
                                **{"crystal_ppm = 39.12": f"crystal_ppm = {ppm}"})
        junit = where / f"junit-{n}.xml"
        proc = pytest_run([str(REPO / "suites" / "test_rtc_drift.py"), str(FLIP), "--bench", str(profile),
                           f"--junitxml={junit}", f"--hil-html={where / 'reports' / 'report.html'}",
                           f"--rootdir={REPO}"], url, where, HIST_FLIP=outcome, HIL_STATE_DIR=str(where / "state"))
        assert proc.wait(timeout=300) in (0, 1), (where / "out.txt").read_text()
        junits.append(junit)
    return url, junits


def _junit_measurements(junit: Path) -> dict[str, float]:
    return {p.get("name").removeprefix("hil.measure."): float(p.get("value"))
            for p in ET.parse(junit).getroot().iter("property")
            if p.get("name").startswith("hil.measure.") and p.get("name").count(".") == 2}


def _rows(text: str, title: str) -> list[list[str]]:
    """The tab-separated rows under ``# title…`` (plain output), header left out."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"# {title}"))
    rows = []
    for line in lines[start + 2:]:
        if line.startswith("# ") or "\t" not in line:
            break
        rows.append(line.split("\t"))
    return rows


def test_compare_names_exactly_the_tests_and_measurements_that_changed(recorded):
    url, _ = recorded
    code, out = history("compare", "1", "3", url=url)
    assert code == 0, out
    assert _rows(out, "tests that changed outcome") == [[DRIFT_TEST, "passed", "failed"]]
    moved = {(r[0], r[1]) for r in _rows(out, "measurements that moved")}
    direction = "suites/test_rtc_drift.py::test_d4054_largest_codes_of_both_signs_change_the_rate_by_table_1s_amount"
    kept = "suites/test_rtc_drift.py::test_d4054_correction_stays_in_force_across_a_set_of_the_clock"
    assert moved == {(DRIFT_TEST, "drift_uncompensated"), (DRIFT_TEST, "drift_residual"),
                     (direction, "d4054_largest_correction"), (direction, "d4054_most_negative_correction"),
                     (kept, "d4054_rate_change_at_a_set")}
    differs = {r[0] for r in _rows(out, "what differs between the runs")}
    assert differs == {"profile", "profile_sha256", "verdict"}  # same PLC, suites commit and harness
    code, same = history("compare", "1", "2", url=url)
    assert _rows(same, "tests that changed outcome") == [[FLIP_TEST, "passed", "failed"]]
    assert _rows(same, "measurements that moved") == []  # the same profile: the drift is the same to 6 digits


def test_trend_of_the_drift_tables_and_plots_every_run(recorded, tmp_path):
    url, junits = recorded
    png = tmp_path / "drift.png"
    code, out = history("trend", "drift_uncompensated", "--bench", "drift-bench", "--plot", str(png), url=url)
    assert code == 0, out
    expected = [_junit_measurements(j)["drift_uncompensated"] for j in junits]
    assert [float(r[4]) for r in _rows(out, "drift_uncompensated")] == expected
    assert expected[0] == expected[1] < expected[2]  # the profiles' crystals, slowest first
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image
    assert matplotlib.image.imread(str(png)).shape[:2] == (400, 900)
    from hil.history.analysis import trend_figure
    from hil.history.store import Store
    store = Store(url)
    rows = store.measurement_history("drift_residual", bench="drift-bench")
    store.close()
    axes = trend_figure("drift_residual", rows).axes[0]
    value_line, low, high = axes.lines
    assert list(value_line.get_ydata()) == [r["value"] for r in rows if r["value"] is not None]
    assert set(low.get_ydata()) == {-0.088} and set(high.get_ydata()) == {0.088}


def test_flaky_finds_the_test_made_to_flip_and_not_a_change_of_profile(recorded):
    url, _ = recorded
    code, out = history("flaky", url=url)
    assert code == 0, out
    found = _rows(out, "flaky tests")
    assert [(r[0], r[1], r[2], r[3]) for r in found] == [(FLIP_TEST, "drift-bench", "1", "P F")]


def test_first_pass_yield_per_test_and_over_runs(recorded):
    url, _ = recorded
    code, out = history("yield", url=url)
    by_test = {r[0].split("::")[-1]: r[1:] for r in _rows(out, "first-pass yield")}
    assert by_test["test_flip"] == ["3", "2", "67%"]
    assert by_test["test_drift_measured_compensated_and_remeasured"] == ["3", "2", "67%"]
    assert by_test["test_table_codes_of_the_manuals_worked_examples"] == ["3", "3", "100%"]
    assert "runs that passed every test first time: 1 of 3 (33%)" in out


def test_export_as_json_and_csv(recorded, tmp_path):
    import csv
    import json
    url, junits = recorded
    code, _ = history("export", "--what", "measurements", "--format", "json", "-o", str(tmp_path / "m.json"),
                      url=url)
    rows = json.loads((tmp_path / "m.json").read_text())
    assert code == 0 and len(rows) == 3 * 6  # 5 drift measurements and the flip test's, each run
    measured = [r for r in rows if r["value"] is not None]
    assert sorted((r["run"], r["name"], f"{r['value']:g}") for r in measured) == sorted(  # JUnit writes %g
        (n + 1, name, f"{value:g}") for n, j in enumerate(junits) for name, value in _junit_measurements(j).items())
    history("export", "--what", "runs", "-o", str(tmp_path / "runs.csv"), url=url)
    runs = list(csv.DictReader((tmp_path / "runs.csv").open()))
    assert [r["verdict"] for r in runs] == ["PASSED", "FAILED", "FAILED"]


def test_each_html_report_shows_the_bench_s_history(recorded):
    url, _ = recorded
    from hil.history.store import Store
    store = Store(url)
    runs = store.runs(newest_first=False)
    measured = [sum(len(t["measurements"]) for t in store.tests_of(r["id"])) for r in runs]
    store.close()
    pages = [Path(r["report"]).read_text(encoding="utf-8") for r in runs]
    assert "first run recorded on this bench" in pages[0] and "<svg" not in pages[0]
    changed = [(n, re.findall(r"<li><code>([^<]+)</code>: (\w+) → (\w+)</li>", page)) for n, page in enumerate(pages)]
    assert changed == [(0, []), (1, [(FLIP_TEST, "passed", "failed")]),
                       (2, [(DRIFT_TEST, "passed", "failed"), (FLIP_TEST, "failed", "passed")])]
    assert "since the last run on this bench (#1" in pages[1] and "1 test changed outcome" in pages[1]
    assert "since the last run on this bench (#2" in pages[2] and "2 tests changed outcome" in pages[2]
    for n in range(1, 3):
        link = re.search(r'<a href="([^"]+)">previous report</a>', pages[n]).group(1)
        assert (Path(runs[n]["report"]).parent / link).resolve() == Path(runs[n - 1]["report"]).resolve()
        assert pages[n].count('<svg class="spark"') == measured[n]  # every measurement, with its earlier values
        assert f"last {n} run{'s' if n > 1 else ''} on this bench" in pages[n]
