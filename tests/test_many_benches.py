"""``hil run --bench a --bench b``: two emulator benches in parallel, one JUnit file each plus a merged one."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.cli.many import merge, plan
from hil.core.errors import HilError
from tests.conftest import EMULATOR_BENCH


def bench_copy(tmp_path: Path, name: str, target: str = "emulator") -> Path:
    text = Path(EMULATOR_BENCH).read_text()
    text = re.sub(r'(?m)^name\s*=.*$', f'name = "{name}"', text, count=1)
    text = re.sub(r'(?m)^target\s*=.*$', f'target = "{target}"', text, count=1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def test_two_emulator_benches_in_parallel(tmp_path, capsys):
    a = bench_copy(tmp_path, "bench-a")
    b = bench_copy(tmp_path, "bench-b", target="emulator+fatek-tcp")
    junit = tmp_path / "reports" / "junit.xml"
    code = main(["run", "--bench", str(a), "--bench", str(b), "--junitxml", str(junit), "--html",
                 str(junit.parent / "report.html"), "--", "-q", "-k",
                 "smoke or test_rtc.py"])
    logs = "".join(p.read_text() for p in junit.parent.glob("run-*.log"))
    assert code == 0, logs
    for name in ("bench-a", "bench-b"):
        own = ET.parse(junit.parent / f"junit-{name}.xml").getroot()
        assert sum(int(s.get("tests")) for s in own.iter("testsuite")) > 10
    merged = ET.parse(junit).getroot()
    assert merged.tag == "testsuites"
    suites = merged.findall("testsuite")
    assert [s.get("name") for s in suites] == ["bench-a", "bench-b"]
    assert int(merged.get("tests")) == sum(int(s.get("tests")) for s in suites)
    assert int(merged.get("failures")) == int(merged.get("errors")) == 0
    # each bench ran against its own target: the per-test round trips are recorded for both
    for suite in suites:
        assert suite.findall(".//property[@name='hil_requests']")
    assert "bench-a" in capsys.readouterr().out


def test_each_bench_keeps_its_own_traces_and_one_html_has_a_section_per_bench(tmp_path, capsys):
    a, b = bench_copy(tmp_path, "bench-a"), bench_copy(tmp_path, "bench-b")
    junit = tmp_path / "reports" / "junit.xml"
    html = tmp_path / "reports" / "report.html"
    code = main(["run", "--bench", str(a), "--bench", str(b), "--junitxml", str(junit), "--html", str(html), "--",
                 "-q", "-k", "smoke", "--hil-trace", "all"])
    assert code == 0
    traces = {name: sorted(p.name for p in (junit.parent / f"traces-{name}").glob("*.txt"))
              for name in ("bench-a", "bench-b")}
    assert traces["bench-a"] and traces["bench-a"] == traces["bench-b"]  # the same tests, a file each
    files = {p.get("value") for p in ET.parse(junit).getroot().iter("property") if p.get("name") == "hil.trace_file"}
    assert any("traces-bench-a" in f for f in files) and any("traces-bench-b" in f for f in files)
    page = html.read_text()
    assert "<h2>bench bench-a — " in page and "<h2>bench bench-b — " in page
    out = capsys.readouterr().out
    assert re.search(r"bench bench-a: PASSED \(exit 0\) after [\d.]+ s — 5 passed$", out, re.M), out
    assert "merged HTML" in out


def test_benches_sharing_a_name_or_a_plc_are_refused(tmp_path):
    a = bench_copy(tmp_path, "same")
    other = tmp_path / "other"
    other.mkdir()
    b = bench_copy(other, "same")
    with pytest.raises(HilError, match="both named"):
        plan([str(a), str(b)], str(tmp_path / "junit.xml"))
    c = bench_copy(tmp_path, "plc-1", target="fatek+tcp://192.0.2.1:500")
    d = bench_copy(tmp_path, "plc-2", target="fatek+tcp://192.0.2.1:500")
    with pytest.raises(HilError, match="both reach"):
        plan([str(c), str(d)], str(tmp_path / "junit.xml"))


def test_a_bench_without_junit_appears_as_an_error(tmp_path):
    good = tmp_path / "junit-good.xml"
    good.write_text('<testsuites><testsuite name="pytest" tests="2" failures="0" errors="0" skipped="0">'
                    '<testcase classname="x" name="a"/><testcase classname="x" name="b"/></testsuite></testsuites>')
    root = merge([("good", good, 0, tmp_path / "g.log"), ("dead", tmp_path / "missing.xml", 3, tmp_path / "d.log")],
                 tmp_path / "junit.xml")
    assert [s.get("name") for s in root] == ["good", "dead"]
    assert root.get("tests") == "3" and root.get("errors") == "1"
    assert root.get("name") == "hil run on benches good, dead"  # not pytest's "pytest tests"
    ET.parse(tmp_path / "junit.xml")  # valid XML on disk
