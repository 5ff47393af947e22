"""hil's own outputs, registered as output callbacks (:mod:`hil.plugin.reporting.outputs`): the records file
(``--hil-records``), the HTML report (``--hil-html``), the JUnit file (pytest's ``--junitxml``, finished with the
bench's properties, the verdict and the traces) and the console (the header panel, the summary by area, the
verdict's last lines)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hil.plugin.reporting.console import header_panel, render, summary_table
from hil.plugin.reporting.html import write_html
from hil.plugin.reporting.junit import finish_junit, write_incomplete
from hil.plugin.reporting.model import records_to_json
from hil.plugin.reporting.outputs import Moment, RunRecord, register_output
from hil.plugin.safety import RECOVERY_NOTES


def _red_line(run: RunRecord, text: str) -> None:
    reporter = run.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(text, red=True)


# -- the records file -------------------------------------------------------------------------------------------------
def records_output(moment: Moment, run: RunRecord) -> None:
    """The report's records as JSON at the end (``hil run --bench a --bench b`` merges them)."""
    value = run.config.getoption("--hil-records")
    if moment is not Moment.FINISHED or not value or run.verdict is None:
        return
    path = Path(value)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(records_to_json(list(run.records.values()), run.properties + run.verdict.properties()),
                    encoding="utf-8")


# -- HTML -------------------------------------------------------------------------------------------------------------
def html_output(moment: Moment, run: RunRecord) -> None:
    """INCOMPLETE from the start of the run, the whole report at its end."""
    if run.html_path is None:
        return
    if moment is Moment.STARTED and run.verdict is not None and not run.config.option.collectonly:
        write_html(run.html_path, [], run.properties + run.verdict.properties(), verdict=run.verdict)
    elif moment is Moment.FINISHED and run.verdict is not None:
        try:
            run.html_written = write_html(run.html_path, run.records.values(),
                                          run.properties + run.verdict.properties(), verdict=run.verdict,
                                          history=run.annotations)
        except OSError as exc:
            _red_line(run, f"hil: could not write the HTML report {run.html_path}: {exc}")


# -- JUnit ------------------------------------------------------------------------------------------------------------
def junit_output(moment: Moment, run: RunRecord) -> None:
    """INCOMPLETE from the start of the run; once pytest wrote its file: the bench's name, properties, the verdict
    and the traces."""
    xmlpath = run.xmlpath
    if xmlpath is None:
        return
    if moment is Moment.STARTED and run.verdict is not None and not run.config.option.collectonly:
        write_incomplete(xmlpath, suite_name=run.state.profile.name,
                         properties=run.properties + run.verdict.properties(), message=run.verdict.stopped)
    elif moment is Moment.CLOSED:
        if not xmlpath.is_file() or not run.uses_bench:
            return
        try:
            name = run.state.profile.name if run.state is not None else None
        except Exception:  # noqa: BLE001 - an unreadable profile was reported already; keep pytest's name
            name = None
        try:
            recovery = [("hil_bench_recovery", note) for note in run.config.stash.get(RECOVERY_NOTES, [])]
            verdict = run.verdict.properties() if run.verdict is not None else []
            finish_junit(xmlpath, suite_name=name, properties=run.properties + verdict + recovery,
                         traces=run.junit_traces)
        except (OSError, ET.ParseError) as exc:
            _red_line(run, f"hil: could not add the bench to {xmlpath}: {exc}")


# -- the console ------------------------------------------------------------------------------------------------------
def console_output(moment: Moment, run: RunRecord) -> None:
    reporter = run.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None:
        return
    tw = run.config.get_terminal_writer()
    if moment is Moment.STARTED and run.config.get_verbosity() >= 0:
        reporter.write(render(header_panel(_header_rows(run), color=tw.hasmarkup), color=tw.hasmarkup,
                              width=tw.fullwidth))
    elif moment is Moment.SUMMARY and run.uses_bench and run.config.get_verbosity() >= -1 and run.records:
        reporter.write(render(summary_table(run.records.values(), color=tw.hasmarkup), color=tw.hasmarkup,
                              width=tw.fullwidth))
    elif moment is Moment.FINISHED:
        _say_verdict(run, reporter)


def _header_rows(run: RunRecord) -> list[tuple[str, str]]:
    state = run.state
    plc_line = getattr(state, "plc_line", "")
    shown = [("bench", f"{state.profile.name} ({state.profile.path})")]
    props = dict(run.properties)
    if "hil.lab.place" in props:
        shown.append(("labgrid", f"place {props['hil.lab.place']} ({props.get('hil.lab.tags', '')}) on "
                                 f"{props.get('hil.lab.exporter', '')}, coordinator "
                                 f"{props.get('hil.lab.coordinator', '')}"))
    wire = props.get("hil.wire", "-")
    plc = plc_line.removeprefix("hil PLC: ").removesuffix(f" via {wire}")  # the wire has its own row
    shown += [("target", props.get("hil.target", "")), ("wire", wire), ("PLC", plc or "-")]
    plc_rows = [(k.removeprefix("hil.plc.").replace("_", " "), v) for k, v in run.properties
                if k.startswith("hil.plc.")]
    sizes = [(k.removesuffix(" size"), v) for k, v in plc_rows if k.endswith(" size")]
    shown += [row for row in plc_rows if not row[0].endswith(" size")]
    if sizes:  # FATEK command 53's memory sizes: one row, not one per memory (JUnit keeps each)
        shown.append(("memory", ", ".join(f"{k} {v}" for k, v in sizes)))
    shown += [("operator", f"{props.get('hil.operator', '')} at {props.get('hil.station', '')}"),
              ("suites", props.get("hil.suites_commit", "")),
              ("harness", f"hil {props.get('hil.harness_version', '')}")]
    return shown


def _say_verdict(run: RunRecord, reporter: pytest.TerminalReporter) -> None:
    """The console's last lines, at every verbosity (-qq too): the verdict, then where the reports are."""
    if run.verdict is None or not run.uses_bench or run.config.option.collectonly:
        return
    good = run.verdict.passed
    reporter.ensure_newline()
    if run.after_progress:
        reporter.write("\n")
    reporter.write_line(f"hil: {run.verdict.line()}", green=good, red=not good, bold=not good)
    written = [p for p in (run.xmlpath, run.html_written) if p is not None]
    if written:
        reporter.write_line("hil: reports " + ", ".join(str(p) for p in written))


# in this order: the console's last lines name the files the others wrote
register_output("records", records_output)
register_output("html", html_output)
register_output("junit", junit_output)
register_output("console", console_output)
