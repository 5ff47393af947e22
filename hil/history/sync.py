"""``hil history sync``: the runs the local spool kept while their store was unreachable, uploaded to the store.

A run is matched by its UUID: one that reached the store before it failed gets the rest of its tests and its end;
one that never reached it is copied whole.  What was uploaded leaves the spool."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import delete, insert, select, update

from hil.history.schema import measurements, recoveries, runs, tests
from hil.history.store import Store

_END = ("ended_at", "finished", "verdict", "stopped", "not_run", "plc_restored", "report")


@dataclass
class Synced:
    runs: int = 0
    tests: int = 0


def sync(spool: Store, store: Store) -> Synced:
    done = Synced()
    with spool.engine.connect() as src:
        pending = [dict(r._mapping) for r in src.execute(select(runs).order_by(runs.c.id))]
    for run in pending:
        local_id = run.pop("id")
        with spool.engine.connect() as src:
            run_tests = [dict(t._mapping) for t in src.execute(select(tests).where(tests.c.run_id == local_id)
                                                               .order_by(tests.c.id))]
            values = [dict(m._mapping) for m in src.execute(select(measurements)
                                                            .where(measurements.c.run_id == local_id))]
            notes = [r.note for r in src.execute(select(recoveries.c.note).where(recoveries.c.run_id == local_id))]
        with store.engine.begin() as dst:
            found = dst.execute(select(runs.c.id, runs.c.finished).where(runs.c.uuid == run["uuid"])).first()
            if found is None:
                run_id = int(dst.execute(insert(runs).values(**run)).inserted_primary_key[0])
            else:
                run_id = found.id
                if run["finished"] or not found.finished:
                    dst.execute(update(runs).where(runs.c.id == run_id).values(**{k: run[k] for k in _END}))
            have = {(t.nodeid, t.attempt) for t in dst.execute(select(tests.c.nodeid, tests.c.attempt)
                                                                .where(tests.c.run_id == run_id))}
            for t in run_tests:
                old_id = t.pop("id")
                if (t["nodeid"], t["attempt"]) in have:
                    continue
                new_id = int(dst.execute(insert(tests).values(**{**t, "run_id": run_id})).inserted_primary_key[0])
                rows = [{**{k: v for k, v in m.items() if k != "id"}, "test_id": new_id, "run_id": run_id}
                        for m in values if m["test_id"] == old_id]
                if rows:
                    dst.execute(insert(measurements), rows)
                done.tests += 1
            if notes and dst.execute(select(recoveries.c.id).where(recoveries.c.run_id == run_id)).first() is None:
                dst.execute(insert(recoveries), [{"run_id": run_id, "note": n} for n in notes])
        with spool.engine.begin() as src:  # uploaded: out of the spool (the store committed it above)
            src.execute(delete(measurements).where(measurements.c.run_id == local_id))
            src.execute(delete(tests).where(tests.c.run_id == local_id))
            src.execute(delete(recoveries).where(recoveries.c.run_id == local_id))
            src.execute(delete(runs).where(runs.c.id == local_id))
        done.runs += 1
    return done
