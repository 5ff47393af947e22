"""The requirement catalogue, the spec() marker, the JUnit property, the HTML requirement table and ``hil spec``."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy  # noqa: F401 - imported before pytester's in-process runs, which would unload it (numpy loads once)
import pytest

from hil.cli.main import main
from hil.core.errors import HilError
from hil.plugin.reporting import model
from hil.plugin.reporting.requirements import requirements_section, verdict
from hil.plugin.requirements import load, parse
from tests.conftest import EMULATOR_BENCH, REPO

MARKED = """
import pytest

@pytest.mark.spec("RTC-REG-2", "RTC-READ-1")
def test_checks_r4135(bench, measure):
    measure("r4135", 3373, unit="", low=0, high=0x173B)

@pytest.mark.spec("RTC-RUN-2")
def test_leans_on_a_choice(bench, request):
    # an [our choice] ID makes the test need spec_choices (the in-process emulator offers it; a wire to a PLC not)
    needs = [m for m in request.node.iter_markers("needs") if "spec_choices" in m.args]
    assert needs and "RTC-RUN-2" in needs[0].kwargs["reason"]

def test_names_nothing(bench):
    pass
"""


def test_the_suites_trace_every_statement_hil_spec_exits_0():
    """CI's check: every statement has a test or a reason, and no test names an unknown ID."""
    assert main(["spec", "--suites", str(REPO / "suites")]) == 0


def test_hil_spec_fails_on_an_unknown_id_and_on_a_statement_without_test_or_reason(tmp_path, capsys, monkeypatch):
    suites = tmp_path / "suites"
    suites.mkdir()
    (suites / "test_x.py").write_text('import pytest\n\n@pytest.mark.spec("RTC-NOPE-9")\ndef test_a():\n    pass\n')
    assert main(["spec", "--suites", str(suites)]) == 4
    assert "RTC-NOPE-9" in capsys.readouterr().out
    (suites / "test_x.py").unlink()  # (a new module name: this process has imported test_x already)
    (suites / "test_y.py").write_text('import pytest\n\n@pytest.mark.spec("RTC-REG-2")\ndef test_a():\n    pass\n')
    assert main(["spec", "--suites", str(suites)]) == 1  # every other tested statement now has neither
    out = capsys.readouterr().out
    assert "RTC-REG-1 has neither a test nor a reason" in out and "RTC-REG-2 has" not in out


def test_catalogue_covers_the_manual_chapters_and_flags_our_choices():
    catalogue = load()
    prefixes = {rid.split("-")[0] for rid in catalogue}
    assert {"RTC", "TEMP", "PID", "S7", "FATEK"} <= prefixes
    choices = {rid for rid, r in catalogue.items() if r.choice}
    assert {"RTC-RUN-2", "PID-DIS-1", "RTC-ADJ-4"} <= choices
    assert all(r.statement.startswith("[our choice]") for rid, r in catalogue.items() if rid in choices)


@pytest.mark.parametrize("text, complaint", [
    ('[[requirement]]\nid = "A-1"\nmanual = "x"\nspec = "y"\n', "missing statement"),
    ('[[requirement]]\nid = "A-1"\nmanual = "x"\nspec = "y"\nstatement = "s"\nuntested = { kind = "later", '
     'reason = "r" }\n', "untested must be"),
    ('[[requirement]]\nid = "A-1"\nmanual = "x"\nspec = "y"\nstatement = "s"\n' * 2, "used twice"),
    ('[[requirement]]\nid = "A-1"\nmanual = "x"\nspec = "y"\nstatement = "s"\nchoice = true\n', "[our choice]"),
    ('[[requirement]]\nid = "A-1"\nmanual = "x"\nspec = "y"\nstatement = "s"\ntests = ["t"]\n', "unknown keys"),
])
def test_a_bad_catalogue_is_one_clear_error(text, complaint):
    with pytest.raises(HilError, match=complaint.replace("[", r"\[").replace("]", r"\]")):
        parse(text, "bad.toml")


def test_junit_carries_the_ids_html_has_the_table_and_a_choice_needs_spec_choices(pytester):
    """(The skip itself, on a bench that does not offer spec_choices, is the needs() marker's: test_bench_mode.py.)"""
    pytester.makepyfile(test_marked=MARKED)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "--target", "emulator+fatek-tcp",
                                          "--junitxml", "junit.xml", "--hil-html", "report.html",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(passed=3)
    cases = {c.get("name"): c for c in ET.parse(pytester.path / "junit.xml").getroot().iter("testcase")}
    props = {name: {p.get("name"): p.get("value") for p in case.iter("property")} for name, case in cases.items()}
    assert props["test_checks_r4135"]["hil.requirements"] == "RTC-REG-2 RTC-READ-1"
    assert props["test_leans_on_a_choice"]["hil.requirements"] == "RTC-RUN-2"
    assert "hil.requirements" not in props["test_names_nothing"]
    page = (pytester.path / "report.html").read_text(encoding="utf-8")
    table = page[page.index('<table class="requirements">'):]
    table = table[:table.index("</table>")]
    for text in ("RTC-REG-2", "RTC-READ-1", "RTC-RUN-2", "test_checks_r4135", "r4135 = 3373 ", "PASS",
                 "R4135 holds the hour"):
        assert text in table, text
    assert "test_names_nothing" not in table
    row = table[table.index("<code>RTC-RUN-2</code>"):]
    assert 'badge passed">passed' in row[:200]


def test_requirement_verdict_never_counts_a_skip_as_evidence():
    assert verdict(["passed", "skipped"]) == "passed"
    assert verdict(["skipped", "skipped"]) == "skipped"
    assert verdict(["passed", "failed"]) == "failed"
    assert verdict(["error"]) == "failed"
    assert verdict(["passed", "aborted"]) == "aborted"  # a test cut short is no evidence either
    assert verdict(["passed", "incomplete"]) == "aborted" and verdict(["aborted", "failed"]) == "failed"
    assert requirements_section([model.TestRecord("t::a", "x")]) == ""


def test_unknown_id_in_a_run_is_a_usage_error(pytester):
    pytester.makepyfile(test_bad='import pytest\n\n@pytest.mark.spec("PID-NOPE-1")\ndef test_a(bench):\n    pass\n')
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*test_bad.py::test_a: spec() names PID-NOPE-1*"])


def test_the_requirement_table_shows_a_measurement_as_the_measurement_table_does():
    """One wording of a measurement: a float's representation error (45.15999999999999) never reaches the table."""
    from hil.core.measurement import Measurement

    settle = Measurement("pid_settle_time", 45.16 - 1e-14, "s", None, 600.0)
    record = model.TestRecord("suites/test_pid_control.py::test_closed_loop", "PID", "passed", 2.0,
                              measurements=[settle], requirements=["PID-LAW-2"])
    html = requirements_section([record])
    assert "pid_settle_time = 45.16 s &lt;= 600 PASS" in html and "45.1599" not in html
