"""The smaller report items of issue 24: measurements a skipped test never took, the header panel, the RTC-chip row
on Modbus, HTML links, ids and headings, earlier runs' files, ``hil run -qq``'s last lines."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from hil.plugin.reporting.console import render, summary_table
from hil.plugin.reporting.html import write_html
from hil.plugin.reporting.model import Measurement
from hil.plugin.reporting.model import TestRecord as Record
from tests.conftest import EMULATOR_BENCH
from tests.test_verdicts import run_tiny

ONE = "def test_one(bench):\n    pass\n"


def _table(records: list[Record]) -> str:
    return render(summary_table(records, color=False), color=False, width=140)


def test_a_skipped_tests_unset_measurements_are_not_out_of_limits():
    declared = Measurement("drift", None, "s/day", -0.1, 0.1)
    records = [Record("suites/test_rtc_drift.py::test_a", "drift", "skipped", message="D4054 unreachable",
                          measurements=[declared]) for _ in range(3)]
    records.append(Record("suites/test_rtc_drift.py::test_b", "drift", "passed",
                              measurements=[declared.measured(0.01)]))
    table = _table(records)
    assert "out" not in table.replace("outcome", "") and "1 in limits" in table, table
    assert "not measured" not in table
    # a test that ran and failed before it measured: "not measured", still not "out"
    records.append(Record("suites/test_rtc_drift.py::test_c", "drift", "failed", measurements=[declared]))
    table = _table(records)
    assert "1 in limits, 1 not measured" in table and ", 1 out" not in table, table


def test_unset_measurements_of_a_test_skipped_at_run_time_in_a_session(tmp_path):
    proc, _ = run_tiny(tmp_path, '''
import pytest

@pytest.mark.measures("drift", unit="s/day", low=-0.1, high=0.1)
def test_skips_before_measuring(bench, measure):
    pytest.skip("D4054 cannot be reached over this wire")
''')
    assert proc.returncode == 0, proc.stdout
    row = next(line for line in proc.stdout.splitlines() if line.startswith("| tiny"))
    assert "out" not in row and "measured" not in row, row


def _panel(lines: list[str]) -> list[str]:
    start = next(i for i, line in enumerate(lines) if "hil bench" in line and line.startswith("+-"))
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("+--"))
    return lines[start:end + 1]


def test_header_panel_gives_the_memory_sizes_one_row_and_junit_each(tmp_path):
    proc, out = run_tiny(tmp_path, ONE, target="emulator+fatek-tcp")
    assert proc.returncode == 0, proc.stdout
    panel = _panel(proc.stdout.splitlines())
    assert not any(" size " in line for line in panel), panel
    assert sum("memory" in line for line in panel) == 1 and any("R 8072" in line for line in panel), panel
    rows = [line for line in panel if re.match(r"\| \S", line)]  # a row's first line (a long path wraps onto more)
    assert len(rows) <= 16, "\n".join(panel)
    assert not any(re.search(r"\| PLC .* via ", line) for line in panel)  # the wire has its own row
    props = {p.get("name"): p.get("value") for p in ET.parse(out / "junit.xml").iter("property")}
    assert props["hil.plc.R_size"] == "8072"  # JUnit keeps each size


def test_the_rtc_chip_row_on_a_modbus_wire_is_short(tmp_path):
    proc, out = run_tiny(tmp_path, ONE, target="emulator+modbus-tcp")
    assert proc.returncode == 0, proc.stdout
    props = {p.get("name"): p.get("value") for p in ET.parse(out / "junit.xml").iter("property")}
    chip = props["hil.plc.rtc_chip"]
    assert chip.startswith("unavailable: D4053") and len(chip) < 100, chip
    assert sum("D4053" in line for line in _panel(proc.stdout.splitlines())) == 1


def test_html_links_attachments_relative_and_wraps_ids_between_words(tmp_path):
    reports = tmp_path / "reports"
    attached = reports / "attachments" / "suites_test_pid.py_test_x-trace.csv"
    attached.parent.mkdir(parents=True)
    attached.write_text("t,pv\n0,1\n")
    record = Record("suites/test_pid.py::test_closed_loop_settles[point-0]", "PID", "failed", message="x",
                        attachments=[str(attached)])
    page = write_html(reports / "report.html", [record], []).read_text()
    assert 'href="attachments/suites_test_pid.py_test_x-trace.csv"' in page and "file://" not in page
    assert "test_<wbr>closed_<wbr>loop_<wbr>settles[<wbr>point-<wbr>0]" in page
    assert "break-all" not in page  # that broke ids in the middle of a word
    assert "summary :is(h2,h3){display:inline-block" in page  # the ▸/▾ stays on its heading's line


def test_a_run_replaces_what_an_earlier_run_left_beside_its_reports(tmp_path):
    stale = tmp_path / "out" / "attachments" / "old_test-trace.csv"  # run_tiny's reports go to out/
    stale.parent.mkdir(parents=True)
    stale.write_text("from an earlier run")
    proc, _ = run_tiny(tmp_path, ONE)
    assert proc.returncode == 0, proc.stdout
    assert not stale.exists()


def test_hil_run_qq_still_prints_the_verdict_and_the_reports(tmp_path):
    (tmp_path / "test_one.py").write_text(ONE)
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "PY_COLORS")}
    proc = subprocess.run([sys.executable, "-m", "hil.cli.main", "run", "-qq", "--bench", str(EMULATOR_BENCH),
                           "--junitxml", str(out / "junit.xml"), "--html", str(out / "report.html"), "--",
                           str(tmp_path / "test_one.py"), "--rootdir", str(tmp_path), "-p", "no:hypothesispytest",
                           "--assert=plain"], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[-2] == "hil: PASSED", lines
    assert lines[-1] == f"hil: reports {out / 'junit.xml'}, {out / 'report.html'}"
    assert Path(out / "junit.xml").is_file() and Path(out / "report.html").is_file()


# -- hil run --bench a --bench b ------------------------------------------------------------------------------------
def _bench_run(tmp_path: Path, name: str, exit_code: int, records: list[Record]):
    from hil.cli.many import BenchRun
    from hil.plugin.reporting.model import records_to_json
    deep = tmp_path / ("a-rather-long-directory-name-for-reports-" * 2)
    deep.mkdir(exist_ok=True)
    run = BenchRun(name, f"{name}.toml", deep / f"junit-{name}.xml", deep / f"run-{name}.log", exit=exit_code,
                   wall=1.5)
    run.records.write_text(records_to_json(records, [("hil.verdict", "FAILED" if exit_code else "PASSED")]))
    return run


def test_many_benches_summary_in_a_pipe_keeps_whole_paths_and_names_the_failed_tests(tmp_path):
    import io

    from rich.console import Console

    from hil.cli.many import print_summary
    runs = [_bench_run(tmp_path, "emulator-a", 0, [Record("suites/test_smoke.py::test_ok", "smoke")]),
            _bench_run(tmp_path, "emulator-b", 1, [
                Record("suites/test_rtc.py::test_leap_day_sets_m1955", "RTC", "failed",
                       message="call: AssertionError: M1955 = 0, expected 1")])]
    buf = io.StringIO()
    print_summary(Console(file=buf, width=40, force_terminal=False), runs, str(tmp_path / "junit.xml"))
    text = buf.getvalue()
    for r in runs:
        assert str(r.junit) in text and str(r.log) in text, text  # never cut to "reports/junit-emu…"
    assert "…" not in text
    assert ("emulator-b: FAILED suites/test_rtc.py::test_leap_day_sets_m1955 — call: AssertionError: M1955 = 0, "
            "expected 1") in text
    assert "bench emulator-b: FAILED (exit 1)" in text


def test_many_benches_status_on_a_terminal_is_one_line_updated_in_place(tmp_path):
    import io

    from rich.console import Console

    from hil.cli.many import BenchRun, _wait_with_counts
    runs = []
    for name, seconds in (("a", 0.3), ("b", 1.2)):
        log = tmp_path / f"run-{name}.log"
        log.write_text("suites/test_smoke.py ..\n")
        run = BenchRun(name, f"{name}.toml", tmp_path / f"junit-{name}.xml", log, wall=0.0)
        run.process = subprocess.Popen([sys.executable, "-c", f"import time; time.sleep({seconds})"])
        runs.append(run)
    buf = io.StringIO()
    _wait_with_counts(Console(file=buf, width=100, force_terminal=True), runs, every=0.1)
    text = buf.getvalue()
    assert "\x1b[2K" in text  # the status line is erased and redrawn, not printed again below itself
    printed = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text).replace("\r", "\n")
    assert [ln.split(":")[0] for ln in printed.splitlines() if ln.startswith("bench ")] == ["bench a", "bench b"]
