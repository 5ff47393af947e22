"""``hil history sync``: the runs the local spool kept while their store was unreachable, uploaded to the store.

A run is matched by its UUID: one that reached the store before it failed gets the rest of its tests and its end;
one that never reached it is copied whole.  What was uploaded leaves the spool."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Connection, delete, insert, select, update

from hil.history.schema import measurements, recoveries, runs, tests
from hil.history.store import Store, inserted_id, rows

_END = ("ended_at", "finished", "verdict", "stopped", "not_run", "plc_restored", "report")


@dataclass
class Synced:
    runs: int = 0
    tests: int = 0


@dataclass
class _Kept:
    """One run as the spool kept it: its row (without the spool's id), tests, measurements, recovery notes."""
    run: dict[str, Any]
    tests: list[dict[str, Any]] = field(default_factory=list)
    measurements: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def sync(spool: Store, store: Store) -> Synced:
    done = Synced()
    with spool.engine.connect() as src:
        pending = [row["id"] for row in rows(src, select(runs.c.id).order_by(runs.c.id))]
    for local_id in pending:
        kept = _read(spool, local_id)
        with store.engine.begin() as dst:
            run_id = _upload_run(dst, kept.run)
            done.tests += _upload_tests(dst, run_id, kept)
            _upload_notes(dst, run_id, kept.notes)
        _forget(spool, local_id)  # uploaded: out of the spool (the store committed it above)
        done.runs += 1
    return done


def _read(spool: Store, local_id: int) -> _Kept:
    with spool.engine.connect() as src:
        run = rows(src, select(runs).where(runs.c.id == local_id))[0]
        run.pop("id")
        return _Kept(run, rows(src, select(tests).where(tests.c.run_id == local_id).order_by(tests.c.id)),
                     rows(src, select(measurements).where(measurements.c.run_id == local_id)),
                     [r["note"] for r in rows(src, select(recoveries.c.note).where(recoveries.c.run_id == local_id))])


def _upload_run(dst: Connection, run: dict[str, Any]) -> int:
    """The run's id in the store: a new row, or the row it reached the store with, given the run's end now."""
    found = dst.execute(select(runs.c.id, runs.c.finished).where(runs.c.uuid == run["uuid"])).first()
    if found is None:
        return inserted_id(dst.execute(insert(runs).values(**run)))
    if run["finished"] or not found.finished:
        dst.execute(update(runs).where(runs.c.id == found.id).values(**{k: run[k] for k in _END}))
    return int(found.id)


def _upload_tests(dst: Connection, run_id: int, kept: _Kept) -> int:
    """The tests (with their measurements) the store does not have yet; how many."""
    have = {(t.nodeid, t.attempt) for t in dst.execute(select(tests.c.nodeid, tests.c.attempt)
                                                        .where(tests.c.run_id == run_id))}
    added = 0
    for test in kept.tests:
        old_id = test["id"]
        if (test["nodeid"], test["attempt"]) in have:
            continue
        row = {k: v for k, v in test.items() if k != "id"} | {"run_id": run_id}
        new_id = inserted_id(dst.execute(insert(tests).values(**row)))
        values = [{k: v for k, v in m.items() if k != "id"} | {"test_id": new_id, "run_id": run_id}
                  for m in kept.measurements if m["test_id"] == old_id]
        if values:
            dst.execute(insert(measurements), values)
        added += 1
    return added


def _upload_notes(dst: Connection, run_id: int, notes: list[str]) -> None:
    """The recovery notes, once: a run whose notes reached the store already keeps those."""
    if notes and dst.execute(select(recoveries.c.id).where(recoveries.c.run_id == run_id)).first() is None:
        dst.execute(insert(recoveries), [{"run_id": run_id, "note": n} for n in notes])


def _forget(spool: Store, local_id: int) -> None:
    with spool.engine.begin() as src:
        src.execute(delete(measurements).where(measurements.c.run_id == local_id))
        src.execute(delete(tests).where(tests.c.run_id == local_id))
        src.execute(delete(recoveries).where(recoveries.c.run_id == local_id))
        src.execute(delete(runs).where(runs.c.id == local_id))
