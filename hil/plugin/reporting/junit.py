"""Finishing the JUnit file pytest's ``--junitxml`` wrote: the bench's properties, its name, the wire traces.

pytest writes the file with its public options (``record_property``'s ``user_properties`` become testcase
properties); what a plugin cannot add through a public API — testsuite properties from a hook, a testcase's
system-out, the suite's name decided at run time — is added here, to the finished file, with the standard
library's ElementTree.  No pytest internals are touched.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Iterable, Mapping

TRACE_PROPERTY = "hil.trace_file"


def finish_junit(path: Path, *, suite_name: str | None, properties: Iterable[tuple[str, str]],
                 traces: Mapping[str, str]) -> None:
    """Rename every ``<testsuite>`` to ``suite_name`` (the bench), put ``properties`` first in each, and append each
    kept wire trace to the system-out of the testcase whose ``hil.trace_file`` property names it."""
    tree = ET.parse(path)
    root = tree.getroot()
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
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


__all__ = ["finish_junit", "TRACE_PROPERTY"]
