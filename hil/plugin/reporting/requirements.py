"""The HTML report's requirement table: requirement → tests → outcome → measurements (what a lab files).

Built from the records' ``requirements`` (the IDs of each test's ``spec()`` marker) and the catalogue's statements.
A requirement's verdict is ``failed`` when any of its tests failed or errored, else ``aborted`` when one of them
has no result (the run stopped inside it, or it never finished), ``passed`` when at least one passed and none of
those, ``skipped`` when every one of its tests was skipped: a skip never counts as evidence, nor does a test cut
short.
"""

from __future__ import annotations

import html
from collections.abc import Iterable

from hil.plugin.reporting.model import TestOutcome, TestRecord
from hil.plugin.requirements import load


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def verdict(outcomes: Iterable[str]) -> TestOutcome:
    seen = {TestOutcome(o) for o in outcomes}
    if seen & {TestOutcome.FAIL, TestOutcome.ERROR}:
        return TestOutcome.FAIL
    if seen & {TestOutcome.ABORTED, TestOutcome.INCOMPLETE}:
        return TestOutcome.ABORTED
    return TestOutcome.PASS if TestOutcome.PASS in seen else TestOutcome.SKIP


def requirement_rows(records: Iterable[TestRecord]) -> dict[str, list[TestRecord]]:
    """Requirement ID → the records of the tests that name it, in the catalogue's order (unknown IDs last)."""
    by_id: dict[str, list[TestRecord]] = {}
    for record in records:
        for rid in record.requirements:
            by_id.setdefault(rid, []).append(record)
    order = {rid: n for n, rid in enumerate(load())}
    return dict(sorted(by_id.items(), key=lambda kv: (order.get(kv[0], len(order)), kv[0])))


def requirements_section(records: list[TestRecord]) -> str:
    """The table's HTML (empty when no test of the run names a requirement)."""
    rows = requirement_rows(records)
    if not rows:
        return ""
    catalogue = load()
    body = []
    for rid, tests in rows.items():
        req = catalogue.get(rid)
        outcome = verdict(r.outcome for r in tests)
        statement = _e(req.statement) if req else "<em>not in the catalogue</em>"
        source = _e(f"{req.manual} · {req.spec}") if req else ""
        cells = "".join(
            f'<div><span class="badge {r.outcome}">{r.outcome}</span> <code>{_e(r.nodeid)}</code>'
            # (the measurement's own wording: the figures as the measurement table and the console show them)
            + "".join(f'<br><span class="{m.outcome.name}">{_e(m.describe())}</span>' for m in r.measurements)
            + "</div>" for r in tests)
        body.append(f'<tr class="{outcome}-row"><td><code>{_e(rid)}</code></td>'
                    f'<td><span class="badge {outcome}">{outcome}</span></td>'
                    f'<td>{statement}<br><small>{source}</small></td><td>{cells}</td></tr>')
    total = len(catalogue)
    head = (f"<p>{len(rows)} of the catalogue's {total} requirements named by this run's tests; "
            f"<code>hil spec</code> lists every one and why the rest have no test.</p>")
    return head + ("<table class=\"requirements\"><tr><th>requirement</th><th>verdict</th><th>statement</th>"
                   f"<th>tests · measurements</th></tr>{''.join(body)}</table>")

