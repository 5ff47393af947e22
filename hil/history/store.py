"""One history store: open it (migrating its schema to :data:`~hil.history.schema.HEAD`), write a run as it goes,
read runs back.  SQLAlchemy Core 2, one code path for SQLite and PostgreSQL (psycopg 3).

A run is written in small transactions as it goes — its row when it starts (``finished`` false, verdict
INCOMPLETE), each test with its measurements when the test's teardown has reported, the verdict at the end — so
a run killed with SIGKILL leaves every finished test behind and its row says it did not finish.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import uuid as uuidlib
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, and_, create_engine, event, func, insert, select, text, update
from sqlalchemy.engine import Connection, CursorResult, make_url
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.sql import Executable

from hil.core.errors import HilError, InvalidValue
from hil.core.measurement import Measurement
from hil.core.redact import hide_password, hide_passwords
from hil.history.schema import HEAD, measurements, metadata, recoveries, runs, tests

#: seconds a writer waits for another's lock (SQLite) or for the server to answer a connection (PostgreSQL)
WAIT_S = 5.0
_LOCK_ID = 0x68696C  # "hil": the PostgreSQL advisory lock that serialises two hosts migrating one server


def rows(conn: Connection, query: Executable) -> list[dict[str, Any]]:
    """The query's rows as dicts, column name → value."""
    return [dict(row) for row in conn.execute(query).mappings()]


def inserted_id(result: CursorResult[Any]) -> int:
    """The primary key an insert of one row gave it."""
    key = result.inserted_primary_key
    if key is None:  # only an executemany (a list of rows) has none
        raise TypeError("inserted_id() takes the result of a one-row insert")
    return int(key[0])


class StoreUnreachable(HilError):
    """A history store that cannot be opened or read: its URL (password hidden), the reason, what to check."""

    def __init__(self, url: str, exc: BaseException) -> None:
        super().__init__(f"history store {hide_password(url)} unreachable ({one_line(exc)}) — check that its server "
                         f"runs and accepts this user, and the URL (--url, $HIL_HISTORY_URL or the profile's "
                         f"[history] url)")


def one_line(exc: BaseException) -> str:
    """A store's error as one line, without SQLAlchemy's "background" link or any password the driver quoted."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return hide_passwords(text.split(" (Background on this error")[0][:300])


@contextlib.contextmanager
def reaching(url: str) -> Iterator[None]:
    """What goes wrong with the store's connection, as :class:`StoreUnreachable` naming ``url``."""
    try:
        yield
    except SQLAlchemyError as exc:
        raise StoreUnreachable(url, exc) from None


def utcnow() -> dt.datetime:
    return dt.datetime.now(dt.UTC).replace(tzinfo=None)


@dataclass
class RunInfo:
    """What a run's row holds when it starts; ``properties`` are its JUnit testsuite properties."""

    bench: str
    properties: list[tuple[str, str]] = field(default_factory=list)
    started_at: dt.datetime = field(default_factory=utcnow)
    uuid: str = field(default_factory=lambda: str(uuidlib.uuid4()))
    host: str = ""
    pid: int = 0
    report: str | None = None

    def row(self) -> dict[str, Any]:
        props = dict(self.properties)
        plc = {k.removeprefix("hil.plc."): v for k, v in self.properties if k.startswith("hil.plc.")}
        return {"uuid": self.uuid, "bench": self.bench, "target": props.get("hil.target"),
                "transport": props.get("hil.transport"), "plc": plc_text(plc), "rtc_chip": plc.get("rtc_chip"),
                "profile": props.get("hil.profile"), "profile_sha256": props.get("hil.profile_sha256"),
                "suites_commit": props.get("hil.suites_commit"), "harness_version": props.get("hil.harness_version"),
                "operator": props.get("hil.operator"), "station": props.get("hil.station"),
                "lab_place": props.get("hil.lab.place"), "host": self.host, "pid": self.pid,
                "started_at": self.started_at, "finished": False, "verdict": "INCOMPLETE",
                "properties": json.dumps(self.properties), "report": self.report}


def plc_text(identity: dict[str, str]) -> str:
    """The PLC's identity as one comparable text: ``unit_type=…; os_version=…`` (sorted, the RTC chip included)."""
    return "; ".join(f"{k}={v}" for k, v in sorted(identity.items()))


@dataclass
class TestResult:
    nodeid: str
    outcome: str
    area: str = ""
    duration: float = 0.0
    attempt: int = 1
    requirements: Sequence[str] = ()
    message: str = ""
    properties: dict[str, Any] = field(default_factory=dict)
    measurements: Sequence[Measurement] = ()


def _sqlite_setup(engine: Engine) -> None:
    """WAL (readers never wait for a writer; a commit survives the process being killed), a busy timeout (two
    benches writing at once wait for each other, briefly), and BEGIN IMMEDIATE (a transaction takes the write lock
    when it starts, so two writers never deadlock upgrading a read lock)."""
    @event.listens_for(engine, "connect")
    def _connect(dbapi: Any, _record: Any) -> None:
        dbapi.isolation_level = None  # the transactions below, not the driver's own
        cursor = dbapi.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {int(WAIT_S * 1000)}")
        cursor.execute("PRAGMA journal_mode = WAL")
        cursor.execute("PRAGMA synchronous = NORMAL")
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Any) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")


def make_engine(url: str) -> Engine:
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        if parsed.database and parsed.database != ":memory:":
            Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"timeout": WAIT_S})
        _sqlite_setup(engine)
        return engine
    args: dict[str, Any] = {}
    if parsed.get_backend_name() == "postgresql":
        args = {"connect_timeout": max(1, int(WAIT_S))}
    return create_engine(url, connect_args=args, pool_pre_ping=False)


def migrate(engine: Engine) -> str:
    """Bring the store's schema to :data:`HEAD` (Alembic, under a lock: two hosts opening a new store at once
    migrate it once).  Returns the revision it was at ("" for an empty store)."""
    with engine.begin() as conn:
        if engine.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_xact_lock(:id)"), {"id": _LOCK_ID})
        found = current_revision(conn)
        if found != HEAD:
            _alembic_upgrade(conn, HEAD)
    return found


def current_revision(conn: Any) -> str:
    from sqlalchemy import inspect
    if not inspect(conn).has_table("alembic_version"):
        return ""
    return conn.execute(text("SELECT version_num FROM alembic_version")).scalar() or ""


def _alembic_upgrade(conn: Any, revision: str) -> None:
    from alembic import command
    from alembic.config import Config
    config = Config()
    config.set_main_option("script_location", str(Path(__file__).parent / "migrations"))
    config.attributes["connection"] = conn
    command.upgrade(config, revision)


class Store:
    """A store opened for reading and writing (its schema at :data:`HEAD`)."""

    def __init__(self, url: str, *, migrate_schema: bool = True) -> None:
        self.url = url
        self.engine = make_engine(url)
        if migrate_schema:
            migrate(self.engine)

    def close(self) -> None:
        self.engine.dispose()

    # -- writing a run ---------------------------------------------------------------------------------------------
    def start_run(self, info: RunInfo) -> int:
        with self.engine.begin() as conn:
            return inserted_id(conn.execute(insert(runs).values(info.row())))

    def add_test(self, run_id: int, result: TestResult, conn: Any = None) -> int:
        if conn is None:
            with self.engine.begin() as conn:
                return self.add_test(run_id, result, conn)
        test_id = inserted_id(conn.execute(insert(tests).values(
            run_id=run_id, nodeid=result.nodeid, area=result.area, outcome=result.outcome,
            duration=result.duration, attempt=result.attempt, requirements=" ".join(result.requirements),
            message=result.message[:4000], properties=json.dumps(result.properties) if result.properties else None,
            recorded_at=utcnow())))
        rows = [{"test_id": test_id, "run_id": run_id, "name": m.name, "value": m.value, "unit": m.unit,
                 "low": m.low, "high": m.high, "outcome": str(m.outcome)} for m in result.measurements]
        if rows:
            conn.execute(insert(measurements), rows)
        return test_id

    def finish_run(self, run_id: int, *, verdict: str, stopped: str = "", not_run: int = 0, plc_restored: str = "",
                   recovery: Iterable[str] = (), report: str | None = None, ended_at: dt.datetime | None = None,
                   finished: bool = True) -> None:
        values: dict[str, Any] = {"verdict": verdict, "stopped": stopped or None, "not_run": not_run,
                                  "plc_restored": plc_restored or None, "ended_at": ended_at or utcnow(),
                                  "finished": finished}
        if report is not None:
            values["report"] = report
        with self.engine.begin() as conn:
            conn.execute(update(runs).where(runs.c.id == run_id).values(**values))
            notes = [{"run_id": run_id, "note": n} for n in recovery]
            if notes:
                conn.execute(insert(recoveries), notes)

    # -- reading -----------------------------------------------------------------------------------------------------
    def runs(self, *, bench: str | None = None, plc: str | None = None, verdict: str | None = None,
             since: dt.datetime | None = None, until: dt.datetime | None = None, limit: int | None = None,
             newest_first: bool = True) -> list[dict[str, Any]]:
        """Runs with their test counts; ``plc`` matches any part of the PLC's identity, ``verdict`` the status
        (case-insensitive; "not finished" for runs that never finished)."""
        where = []
        if bench:
            where.append(runs.c.bench == bench)
        if plc:
            where.append(runs.c.plc.contains(plc))
        if verdict:
            if verdict.lower() in ("not finished", "unfinished"):
                where.append(runs.c.finished.is_(False))
            else:
                where.append(func.upper(runs.c.verdict) == verdict.upper())
        if since:
            where.append(runs.c.started_at >= since)
        if until:
            where.append(runs.c.started_at < until)
        order = (runs.c.started_at.desc(), runs.c.id.desc()) if newest_first else (runs.c.started_at, runs.c.id)
        query = select(runs).where(and_(True, *where)).order_by(*order)
        if limit:
            query = query.limit(limit)
        with self.engine.connect() as conn:
            found = rows(conn, query)
            counts = self._counts(conn, [r["id"] for r in found])
        for r in found:
            r["counts"] = counts.get(r["id"], {})
        return found

    @staticmethod
    def _counts(conn: Any, run_ids: list[int]) -> dict[int, dict[str, int]]:
        out: dict[int, dict[str, int]] = {}
        for chunk in (run_ids[i:i + 500] for i in range(0, len(run_ids), 500)):
            query = (select(tests.c.run_id, tests.c.outcome, func.count()).where(tests.c.run_id.in_(chunk))
                     .group_by(tests.c.run_id, tests.c.outcome))
            for run_id, outcome, n in conn.execute(query):
                out.setdefault(run_id, {})[outcome] = n
        return out

    def run(self, ref: str) -> dict[str, Any]:
        """A run by its number, its UUID (or a unique prefix of it), ``last`` or ``last~N`` (the Nth before)."""
        ref = ref.strip()
        with self.engine.connect() as conn:
            if ref == "last" or ref.startswith("last~"):
                back = int(ref[5:] or 0) if ref[5:].isdigit() or not ref[5:] else -1
                if back < 0:
                    raise InvalidValue(f"run {ref!r} — write last, or last~N with N a number")
                found = rows(conn, select(runs).order_by(runs.c.started_at.desc(), runs.c.id.desc())
                             .offset(back).limit(1))
            elif ref.isdigit():
                found = rows(conn, select(runs).where(runs.c.id == int(ref)))
            else:
                found = rows(conn, select(runs).where(runs.c.uuid.startswith(ref.lower())).limit(2))
        if not found:
            raise InvalidValue(f"no run {ref!r} in the history ({self.shown}) — `hil history list` shows the runs")
        if len(found) > 1:
            raise InvalidValue(f"run {ref!r} is the start of more than one run's UUID — give more of it")
        return found[0]

    @property
    def shown(self) -> str:
        return hide_password(self.url)

    def tests_of(self, run_id: int) -> list[dict[str, Any]]:
        """The run's tests, each with its ``measurements`` (a list of dicts)."""
        with self.engine.connect() as conn:
            found = rows(conn, select(tests).where(tests.c.run_id == run_id).order_by(tests.c.id))
            by_test: dict[int, list[dict[str, Any]]] = {}
            for m in rows(conn, select(measurements).where(measurements.c.run_id == run_id)
                          .order_by(measurements.c.id)):
                by_test.setdefault(m["test_id"], []).append(m)
        for t in found:
            t["measurements"] = by_test.get(t["id"], [])
        return found

    def recoveries_of(self, run_id: int) -> list[str]:
        with self.engine.connect() as conn:
            return [r.note for r in conn.execute(select(recoveries.c.note).where(recoveries.c.run_id == run_id)
                                                 .order_by(recoveries.c.id))]

    def measurement_history(self, name: str, *, bench: str | None = None, nodeid: str | None = None,
                            run_ids: Sequence[int] | None = None) -> list[dict[str, Any]]:
        """Every recorded value of measurement ``name``, oldest first, with its run's date, bench and PLC."""
        query = (select(measurements.c.value, measurements.c.unit, measurements.c.low, measurements.c.high,
                        measurements.c.outcome, measurements.c.name, tests.c.nodeid, runs.c.id.label("run_id"),
                        runs.c.uuid, runs.c.started_at, runs.c.bench, runs.c.plc)
                 .join(tests, tests.c.id == measurements.c.test_id).join(runs, runs.c.id == measurements.c.run_id)
                 .where(measurements.c.name == name).order_by(runs.c.started_at, runs.c.id, measurements.c.id))
        if bench:
            query = query.where(runs.c.bench == bench)
        if nodeid:
            query = query.where(tests.c.nodeid == nodeid)
        if run_ids is not None:
            query = query.where(runs.c.id.in_(list(run_ids)))
        with self.engine.connect() as conn:
            return rows(conn, query)

    def test_history(self, *, bench: str | None = None, nodeid: str | None = None) -> list[dict[str, Any]]:
        """Every recorded test result, oldest run first, with its run's bench, PLC identity and profile hash."""
        query = (select(tests.c.nodeid, tests.c.outcome, tests.c.attempt, runs.c.id.label("run_id"), runs.c.uuid,
                        runs.c.started_at, runs.c.bench, runs.c.plc, runs.c.profile_sha256)
                 .join(runs, runs.c.id == tests.c.run_id).order_by(runs.c.started_at, runs.c.id, tests.c.id))
        if bench:
            query = query.where(runs.c.bench == bench)
        if nodeid:
            query = query.where(tests.c.nodeid == nodeid)
        with self.engine.connect() as conn:
            return rows(conn, query)

    def bench_history(self, bench: str, before_id: int, n: int) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
        """For the HTML report: the last run on ``bench`` before run ``before_id`` with its tests' outcomes, and the
        measurements of the last ``n`` runs there (oldest first)."""
        with self.engine.connect() as conn:
            earlier = rows(conn, select(runs).where(runs.c.bench == bench, runs.c.id != before_id)
                           .order_by(runs.c.started_at.desc(), runs.c.id.desc()).limit(n))
            if not earlier:
                return None, []
            last = earlier[0]
            last["outcomes"] = {t.nodeid: t.outcome for t in conn.execute(
                select(tests.c.nodeid, tests.c.outcome).where(tests.c.run_id == last["id"]).order_by(tests.c.id))}
            values = rows(conn, select(measurements.c.name, measurements.c.value, measurements.c.low,
                                       measurements.c.high, tests.c.nodeid, runs.c.started_at,
                                       runs.c.id.label("run_id"))
                          .join(tests, tests.c.id == measurements.c.test_id)
                          .join(runs, runs.c.id == measurements.c.run_id)
                          .where(measurements.c.run_id.in_([r["id"] for r in earlier]))
                          .order_by(runs.c.started_at, runs.c.id))
        return last, values


__all__ = ["Store", "StoreUnreachable", "one_line", "reaching", "RunInfo", "TestResult", "migrate", "make_engine",
           "current_revision", "metadata", "utcnow", "rows", "inserted_id"]
