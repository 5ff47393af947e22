"""Finishing the JUnit file pytest's ``--junitxml`` wrote: the bench's properties, its name, the wire traces.

pytest writes the file with its public options (``record_property``'s ``user_properties`` become testcase
properties); what a plugin cannot add through a public API — testsuite properties from a hook, a testcase's
system-out, the suite's name decided at run time — is added here, to the finished file, with the standard
library's ElementTree.  No pytest internals are touched.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from pathlib import Path

TRACE_PROPERTY = "hil.trace_file"


def root_name(benches: Iterable[str]) -> str:
    """The ``<testsuites name=…>`` of a hil run: ``hil run on bench X`` (pytest's own is "pytest tests")."""
    names = list(benches)
    return f"hil run on bench{'es' if len(names) > 1 else ''} {', '.join(names)}" if names else "hil run"


def write_incomplete(path: Path, *, suite_name: str, properties: Iterable[tuple[str, str]], message: str) -> None:
    """What ``path`` says while the run is under way, and still says if the run dies before pytest writes the
    real file (SIGKILL, pytest-timeout's thread method ending the process): one error naming what is unknown —
    never an earlier run's result."""
    root = ET.Element("testsuites", name=root_name([suite_name]))
    suite = ET.SubElement(root, "testsuite", name=suite_name, tests="1", errors="1", failures="0", skipped="0")
    block = ET.SubElement(suite, "properties")
    for name, value in properties:
        ET.SubElement(block, "property", name=name, value=str(value))
    case = ET.SubElement(suite, "testcase", classname="hil.session", name="run")
    ET.SubElement(case, "error", message=message).text = message
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)


def finish_junit(path: Path, *, suite_name: str | None, properties: Iterable[tuple[str, str]],
                 traces: Mapping[str, str]) -> None:
    """Rename every ``<testsuite>`` to ``suite_name`` (the bench) and the root after it, put ``properties`` first in
    each, and append each kept wire trace to the system-out of the testcase whose ``hil.trace_file`` property
    names it."""
    tree = ET.parse(path)
    root = tree.getroot()
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
    if root.tag == "testsuites" and suite_name:
        root.set("name", root_name([suite_name]))
    properties = list(properties)
    for suite in suites:
        if suite_name:
            suite.set("name", suite_name)
        if properties:
            block = suite.find("properties")
            if block is None:
                block = ET.Element("properties")
                suite.insert(0, block)
            have = {(p.get("name"), p.get("value")) for p in block.iter("property")}
            for name, value in properties:
                if (name, str(value)) not in have:
                    ET.SubElement(block, "property", name=name, value=str(value))
        for case in suite.iter("testcase"):
            key = next((p.get("value") for p in case.iter("property") if p.get("name") == TRACE_PROPERTY), None)
            trace = traces.get(key) if key else None
            if not trace:
                continue
            out = case.find("system-out")
            if out is None:
                out = ET.SubElement(case, "system-out")
            out.text = (out.text + "\n" if out.text else "") + trace
    tree.write(path, encoding="utf-8", xml_declaration=True)


__all__ = ["finish_junit", "write_incomplete", "root_name", "TRACE_PROPERTY"]
