"""Reports: JUnit properties and measurements (checked with junitparser), wire traces of failing tests, the HTML
report (self-contained, with plots), plain text in a pipe, and the CLI's help and one-line errors."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy  # noqa: F401 - pytester's in-process runs restore sys.modules, and numpy cannot load twice in a process
import pytest
from junitparser import JUnitXml

from hil.io.trace import describe_modbus
from hil.plugin.reporting.identity import public_url
from hil.plugin.reporting.model import Measurement, Series, area_of
from tests.conftest import EMULATOR_BENCH

ANSI = re.compile(r"\x1b\[|\x1b\]|\x1b[()]")


@pytest.fixture(scope="module")
def hil_run(tmp_path_factory):
    """``hil run -q`` on the emulator into a temp dir, stdout a pipe (as in CI)."""
    out = tmp_path_factory.mktemp("run")
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "PY_COLORS")}
    env.update(HIL_OPERATOR="Test Operator", HIL_STATION="rig-7")
    proc = subprocess.run(
        [sys.executable, "-m", "hil.cli.main", "run", "-q", "--junitxml", str(out / "junit.xml"),
         "--html", str(out / "report.html"), "--", "-k", "drift or smoke or readings_are_in_range"],
        cwd=out, capture_output=True, text=True, env=env, timeout=120)
    return proc, out


def test_hil_run_writes_junit_with_suite_properties_and_measurements(hil_run):
    proc, out = hil_run
    assert proc.returncode == 0, proc.stdout + proc.stderr
    xml = JUnitXml.fromfile(str(out / "junit.xml"))
    suite = next(iter(xml))
    props = {p.name: p.value for p in suite.properties()}
    assert props["hil.bench"] == "emulator"
    assert props["hil.target"] == "emulator"
    assert props["hil.plc.emulator_version"].startswith("hil-emulator")
    assert props["hil.plc.rtc_chip"] == "D4053 = 3 (S-35390A)"
    assert props["hil.operator"] == "Test Operator" and props["hil.station"] == "rig-7"
    assert re.fullmatch(r"[0-9a-f]{64}", props["hil.profile_sha256"])
    assert re.match(r"[0-9a-f]{40}", props["hil.suites_commit"])
    assert props["hil.harness_version"]
    assert suite.tests >= 1 and suite.failures == 0 and suite.errors == 0
    limited = {}
    for case in suite:  # junitparser has no testcase properties API: read them from its element
        for p in case._elem.iter("property"):
            limited[p.get("name")] = p.get("value")
    assert "hil.measure.drift_residual" in limited, sorted(limited)
    assert limited["hil.measure.drift_residual.unit"] == "s/day"
    assert float(limited["hil.measure.drift_residual.low"]) < 0 < float(limited["hil.measure.drift_residual.high"])
    assert limited["hil.measure.drift_residual.outcome"] == "PASS"
    assert any(k.startswith("hil.measure.point") and k.endswith(".high") for k in limited)


def test_hil_run_html_is_self_contained_with_plots(hil_run):
    _, out = hil_run
    page = (out / "report.html").read_text(encoding="utf-8")
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*https?://""", page, re.I)
    assert "<link" not in page and "<script src" not in page
    plots = re.findall(r'<img class="plot" alt="([^"]*)" src="data:image/png;base64,', page)
    assert any("residual" in alt for alt in plots) and any("uncompensated" in alt for alt in plots)
    assert "drift_residual" in page and "Summary by area" in page and "Test Operator" in page


def test_hil_run_quiet_in_a_pipe_has_no_control_characters(hil_run):
    proc, _ = hil_run
    assert not ANSI.search(proc.stdout) and not ANSI.search(proc.stderr)
    assert "\r" not in proc.stdout
    assert "hil results by area" in proc.stdout and "drift" in proc.stdout
    assert "+--" in proc.stdout  # ASCII boxes in a log


FAILING = """
    def test_writes_then_fails(bench):
        bench.plc.io.write_words("R1000", [11, 22])
        assert bench.plc.io.read_words("R1000", 2) == [0, 0], "deliberate failure"

    def test_passes(bench):
        bench.plc.io.read_words("R1000", 2)

    def test_measures_out_of_limits(bench, measure):
        measure("supply_voltage", 25.1, unit="V", low=20.4, high=24.0, note="check the PSU")
        raise AssertionError("not reached")
"""


def _cases(path):
    return {case.get("name"): case for case in ET.parse(path).getroot().iter("testcase")}


def test_failing_test_carries_its_wire_trace_in_junit_and_a_file(pytester):
    pytester.makepyfile(test_breaks=FAILING)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "--target", "emulator+fatek-tcp",
                                          "--junitxml=out/junit.xml", "-o", "junit_family=xunit1",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=2)
    cases = _cases(pytester.path / "out" / "junit.xml")
    trace = cases["test_writes_then_fails"].find("system-out").text
    assert "wire trace (fatek)" in trace
    assert re.search(r"-> 02 30 31 34 37 .*WriteRegisters|-> 02 30 31 34 37 .*R01000", trace), trace[:800]
    assert re.search(r"<- 02 30 31 34 37 ", trace)  # the reply frames: STX "01" "47"
    assert cases["test_passes"].find("system-out") is None  # default: failures only
    saved = list((pytester.path / "out" / "traces").glob("*test_writes_then_fails*.txt"))
    assert saved and "wire trace (fatek)" in saved[0].read_text()
    props = {p.get("name"): p.get("value") for p in cases["test_measures_out_of_limits"].iter("property")}
    assert props["hil.measure.supply_voltage"] == "25.1" and props["hil.measure.supply_voltage.outcome"] == "FAIL"
    failure = cases["test_measures_out_of_limits"].find("failure").get("message")
    assert "supply_voltage = 25.1 V [20.4, 24] FAIL: check the PSU" in failure


def test_trace_all_keeps_passing_tests_traces_and_html_has_them(pytester):
    pytester.makepyfile(test_ok="""
        def test_passes(bench, report):
            bench.plc.io.read_words("R1000", 2)
            report.attach_pid([(t, 20 + t, 50, 10 * t) for t in range(10)], unit="°C")
    """)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "--target", "emulator+modbus-tcp",
                                          "--junitxml=junit.xml", "--hil-trace=all", "--hil-html=r/report.html",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    trace = _cases(pytester.path / "junit.xml")["test_passes"].find("system-out").text
    assert "wire trace (modbus-tcp)" in trace and "FC03 read holding registers at 1000 ×2" in trace
    page = (pytester.path / "r" / "report.html").read_text()
    assert 'alt="PID closed loop" src="data:image/png;base64,' in page
    assert "FC03 read holding registers" in page


def test_in_process_emulator_records_the_transport_calls(pytester):
    pytester.makepyfile(test_fail="""
        def test_fails(bench):
            bench.plc.io.write_many({"R1010": 4321})
            assert False
    """)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "--target", "emulator",
                                          "--junitxml=junit.xml", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    trace = _cases(pytester.path / "junit.xml")["test_fails"].find("system-out").text
    assert "wire trace (calls)" in trace and "write_many([R1010=4321])" in trace


# -- units ---------------------------------------------------------------------------------------------------------
def test_public_url_drops_credentials():
    assert public_url("modbus+tcp://user:pw@10.0.0.5:502?unit=1&token=abc") == "modbus+tcp://10.0.0.5:502?unit=1"
    assert public_url("emulator+fatek-tcp") == "emulator+fatek-tcp"


@pytest.mark.parametrize("path, area", [
    ("suites/test_rtc.py::test_x", "RTC"), ("suites/test_rtc_validity.py::t", "RTC"),
    ("suites/test_rtc_drift.py::t", "drift"), ("suites/test_temperature.py::t[0]", "temperature"),
    ("suites/test_pid_closed_loop.py::t", "PID"), ("suites/test_smoke.py::t", "smoke"),
    ("suites/s7smart/test_s7_rtc.py::t", "S7"), ("suites/test_other.py::t", "other")])
def test_area_of_a_suite_file(path, area):
    assert area_of(path) == area


def test_measurement_limits_and_series_validation():
    assert Measurement("x", 1.0, low=0, high=1).passed and not Measurement("x", 1.01, high=1).passed
    assert not Measurement("x", float("nan"), low=0).passed
    assert Measurement("x", 5.0).limits_text() == "no limits"
    with pytest.raises(ValueError, match="columns"):
        Series.build("s", [(1, 2)])
    with pytest.raises(ValueError, match="differ in length"):
        Series.build("s", {"t": [1, 2], "y": [1]})
    assert Series.build("s", {"t": [0, 1], "y": [2, 3]}).points == 2


def test_describe_modbus_frames():
    assert describe_modbus(bytes.fromhex("000100000006010310200008"), rtu=False, reply=False) == \
        "tid 1 unit 1 FC03 read holding registers at 4128 ×8"
    assert "exception reply to FC03: code 2" in describe_modbus(bytes.fromhex("0183020000"), rtu=True, reply=True)


# -- CLI -----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [[], ["run"], ["emulate"], ["probe"], ["rtc"], ["rtc", "read"], ["rtc", "set"],
                                  ["rtc", "sync"], ["drift"], ["drift", "code"], ["drift", "decode"],
                                  ["drift", "measure"]])
def test_every_help_has_examples(argv, capsys):
    from hil.cli.main import main
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--help"])
    assert exc.value.code == 0
    assert "example" in capsys.readouterr().out


def test_errors_are_one_line_without_traceback(capsys):
    from hil.cli.main import main
    assert main(["probe", "fatek+serial:///dev/ttyHIL-none"]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "cannot open /dev/ttyHIL-none" in err and "—" in err
