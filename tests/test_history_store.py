"""The run history against SQLite and a real PostgreSQL server (tests/pg_server.py): runs in their own processes
recording to one store side by side, a run killed with SIGKILL, the store made unreachable in the middle of a run,
and a store of the previous schema version upgraded."""

from __future__ import annotations

import os
import signal
import sqlite3
import threading
import xml.etree.ElementTree as ET

import pytest

# imported before any in-process session (pytester) can import them first: pytester drops what a session imported,
# and numpy's and SQLAlchemy's compiled parts cannot be loaded twice in one process
import hil.families.fbs.sim
import hil.history.store
from tests.history_runs import bench_profile, hil, history, pytest_run, wait_for, write_tests
from tests.pg_server import NO_POSTGRES, Cluster

if NO_POSTGRES is None:
    import psycopg  # noqa: F401
    from sqlalchemy.dialects.postgresql import psycopg as _dialect  # noqa: F401

BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.skipif(NO_POSTGRES is not None,
                                                                           reason=str(NO_POSTGRES)))]


@pytest.fixture(scope="session")
def postgres():
    cluster = Cluster()
    yield cluster
    cluster.stop()


@pytest.fixture(params=BACKENDS)
def store_url(request, tmp_path):
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'store' / 'history.sqlite'}"
    return request.getfixturevalue("postgres").new_database()


def _store(url):
    from hil.history.store import Store
    return Store(url)


def _recorded(url, *names):
    """The newest run's tests, once every one of ``names`` is among them (else None)."""
    store = _store(url)
    try:
        runs = store.runs(limit=1)
        if not runs:
            return None
        done = {t["nodeid"].split("::")[-1]: t for t in store.tests_of(runs[0]["id"])}
        return (runs[0], done) if all(n in done for n in names) else None
    except Exception:  # noqa: BLE001 - the store is being created by the run
        return None
    finally:
        store.close()


def test_two_benches_in_parallel_write_to_one_store(tmp_path, store_url):
    """``hil run --bench a --bench b``: two processes open a new store at once (one migrates it), record side by
    side; each run has every test and measurement of its own."""
    tests = write_tests(tmp_path / "t")
    a, b = bench_profile(tmp_path, "bench-a"), bench_profile(tmp_path, "bench-b")
    done = hil("run", "--bench", str(a), "--bench", str(b), "--junitxml", str(tmp_path / "r" / "junit.xml"), "--",
               str(tests), "-k", "not waits", url=store_url, cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    store = _store(store_url)
    try:
        runs = {r["bench"]: r for r in store.runs()}
        assert sorted(runs) == ["bench-a", "bench-b"]
        for bench, run in runs.items():
            assert run["finished"] and run["verdict"] == "PASSED", run
            recorded = store.tests_of(run["id"])
            junit = ET.parse(tmp_path / "r" / f"junit-{bench}.xml").getroot()
            expected = {f"{tc.get('classname').split('.')[-1]}.py::{tc.get('name')}" for tc in junit.iter("testcase")}
            assert {t["nodeid"].split("/")[-1] for t in recorded} == expected
            assert len(recorded) == 15 and all(t["outcome"] == "passed" for t in recorded)
            values = sorted(m["value"] for t in recorded for m in t["measurements"] if m["name"] == "n")
            assert values == [float(n) for n in range(12)]
    finally:
        store.close()


def test_a_run_killed_with_sigkill_is_marked_not_finished_and_keeps_its_tests(tmp_path, store_url):
    tests = write_tests(tmp_path / "t")
    proc = pytest_run([str(tests), "--bench", str(bench_profile(tmp_path, "killed"))], store_url, tmp_path,
                      HIST_GO=str(tmp_path / "never"))
    try:
        wait_for(lambda: _recorded(store_url, "test_first", "test_second"), "the first two tests in the store")
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    run, done = _recorded(store_url, "test_first", "test_second")
    assert not run["finished"] and run["verdict"] == "INCOMPLETE" and run["ended_at"] is None
    assert sorted(done) == ["test_first", "test_second"]  # the test it was killed in has no result
    assert all(t["outcome"] == "passed" for t in done.values())
    assert [(m["name"], m["value"], m["unit"], m["low"], m["high"], m["outcome"])
            for m in done["test_first"]["measurements"]] == [("first_value", 1.5, "V", 1.0, 2.0, "PASS")]
    code, listed = history("list", url=store_url)
    assert code == 0 and "NOT FINISHED" in listed, listed


def _make_unreachable(url, cluster):
    """SQLite: another process holds the store's write lock for the rest of the run (writers give up after their
    busy timeout); PostgreSQL: the database refuses connections and its open ones are ended."""
    if url.startswith("sqlite"):
        holder = sqlite3.connect(url.removeprefix("sqlite:///"), isolation_level=None, check_same_thread=False)
        holder.execute("BEGIN EXCLUSIVE")
        return holder.close
    database = url.rsplit("/", 1)[1]
    cluster.refuse(database)
    return lambda: cluster.refuse(database, False)


def test_the_store_unreachable_mid_run_leaves_the_verdict_and_warns_once(request, pytester, monkeypatch, tmp_path,
                                                                         store_url):
    """In this process (a thread plays the harness while the session runs): once the first two tests are in the
    store it is made unreachable; the run goes on, says so once, keeps the rest in the spool; sync uploads it."""
    tests = write_tests(tmp_path / "t")
    go = tmp_path / "go"
    monkeypatch.setenv("HIST_GO", str(go))
    monkeypatch.setenv("HIL_HISTORY_URL", store_url)
    cluster = request.getfixturevalue("postgres") if store_url.startswith("postgresql") else None
    restore = []

    def harness() -> None:
        try:
            # (a hang guard under the test's own 120 s: on a busy host the writer's start alone took most of 60 s)
            wait_for(lambda: _recorded(store_url, "test_first", "test_second"), "the first two tests in the store",
                     timeout=100.0)
            restore.append(_make_unreachable(store_url, cluster))
        finally:
            go.touch()
    thread = threading.Thread(target=harness)
    thread.start()
    try:
        result = pytester.runpytest_inprocess(str(tests), "--bench", str(bench_profile(tmp_path, "cut-off")), "-k",
                                              "not quick", f"--junitxml={tmp_path / 'junit.xml'}", "-p",
                                              "no:cacheprovider")
    finally:
        thread.join()
        for undo in restore:
            undo()
    assert restore, "the store was never made unreachable"
    result.assert_outcomes(passed=4)
    warnings = [line for line in result.outlines if "history store" in line]
    assert len(warnings) == 1, result.outlines
    assert "unreachable" in warnings[0] and "hil history sync" in warnings[0]
    assert "hil: PASSED" in result.outlines
    props = {p.get("name"): p.get("value") for p in ET.parse(tmp_path / "junit.xml").getroot().iter("property")}
    assert props["hil.verdict"] == "PASSED"
    run, done = _recorded(store_url, "test_first", "test_second")
    assert not run["finished"] and "test_after" not in done  # the rest went to the local spool
    code, synced = history("sync", url=store_url)
    assert code == 0 and "uploaded 1 run (2 tests)" in synced, synced
    run, done = _recorded(store_url, "test_after")
    assert run["finished"] and run["verdict"] == "PASSED"
    assert sorted(done) == ["test_after", "test_first", "test_second", "test_waits_for_the_harness"]
    assert [m["value"] for m in done["test_after"]["measurements"]] == [2.5]
    assert "uploaded 0 runs" in history("sync", url=store_url)[1]


def test_a_store_of_the_previous_schema_is_upgraded_keeping_its_runs(store_url):
    """A store at revision 0001 (no report column, no recoveries table) with a run in it: opening it migrates it to
    the head revision; the old run reads back whole, and a new run uses what 0002 added."""
    import datetime as dt

    from sqlalchemy import text

    from hil.core.measurement import Measurement
    from hil.history.schema import HEAD
    from hil.history.store import RunInfo, Store, TestResult, _alembic_upgrade, current_revision, make_engine
    engine = make_engine(store_url)
    with engine.begin() as conn:
        _alembic_upgrade(conn, "0001")
        assert current_revision(conn) == "0001"
        conn.execute(text("INSERT INTO runs (uuid, bench, started_at, finished, verdict, plc) VALUES "
                          "('old-run', 'bench-1', :t, :f, 'PASSED', 'os=1.0')"),
                     {"t": dt.datetime(2026, 3, 1, 12, 0), "f": True})
        run_id = conn.execute(text("SELECT id FROM runs WHERE uuid = 'old-run'")).scalar()
        conn.execute(text("INSERT INTO tests (run_id, nodeid, outcome, attempt) VALUES (:r, 'a.py::t', 'passed', 1)"),
                     {"r": run_id})
        test_id = conn.execute(text("SELECT id FROM tests")).scalar()
        conn.execute(text("INSERT INTO measurements (test_id, run_id, name, value, unit, outcome) VALUES "
                          "(:t, :r, 'drift', 3.38, 's/day', 'PASS')"), {"t": test_id, "r": run_id})
    engine.dispose()
    store = Store(store_url)
    try:
        with store.engine.connect() as conn:
            assert current_revision(conn) == HEAD
        old = store.run("old-run")
        assert old["report"] is None and old["plc"] == "os=1.0" and old["started_at"] == dt.datetime(2026, 3, 1, 12)
        assert [(t["nodeid"], [(m["name"], m["value"]) for m in t["measurements"]])
                for t in store.tests_of(old["id"])] == [("a.py::t", [("drift", 3.38)])]
        new = store.start_run(RunInfo("bench-1", [("hil.plc.os", "1.0")], report="/reports/history/x.html"))
        store.add_test(new, TestResult("a.py::t", "failed", measurements=[Measurement("drift", 9.0, "s/day")]))
        store.finish_run(new, verdict="FAILED", recovery=["restored D4054 from the journal"])
        assert store.run(str(new))["report"] == "/reports/history/x.html"
        assert store.recoveries_of(new) == ["restored D4054 from the journal"]
        assert [r["value"] for r in store.measurement_history("drift")] == [3.38, 9.0]
    finally:
        store.close()
