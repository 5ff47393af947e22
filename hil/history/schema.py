"""The store's tables, as the newest migration leaves them (SQLAlchemy Core: one definition for SQLite and
PostgreSQL).  A change here goes with a new revision in ``migrations/versions`` and a new :data:`HEAD`.

Times are UTC without a zone (SQLite keeps no zone; both stores then compare the same way)."""

from __future__ import annotations

from sqlalchemy import (
                        Boolean,
                        Column,
                        DateTime,
                        Float,
                        ForeignKey,
                        Index,
                        Integer,
                        MetaData,
                        String,
                        Table,
                        Text,
                        UniqueConstraint,
)

#: the newest Alembic revision (migrations/versions); a store at another revision is migrated when opened
HEAD = "0002"

metadata = MetaData()

runs = Table(
    "runs", metadata,
    Column("id", Integer, primary_key=True),
    Column("uuid", String(36), nullable=False, unique=True),  # the run's identity across stores (sync)
    Column("bench", String(200), nullable=False),
    Column("target", Text), Column("transport", String(100)),
    Column("plc", Text),  # the PLC's identity as one text (unit type, OS version, sizes …): what "same PLC" means
    Column("rtc_chip", String(200)),
    Column("profile", Text), Column("profile_sha256", String(64)),
    Column("suites_commit", String(100)), Column("harness_version", String(50)),
    Column("operator", String(200)), Column("station", String(200)), Column("lab_place", String(200)),
    Column("host", String(200)), Column("pid", Integer),
    Column("started_at", DateTime, nullable=False),
    Column("ended_at", DateTime),
    Column("finished", Boolean, nullable=False, default=False),  # False: still running, or killed before its end
    Column("verdict", String(40), nullable=False),  # hil.plugin.reporting.verdict's status; INCOMPLETE until the end
    Column("stopped", Text), Column("not_run", Integer), Column("plc_restored", Text),
    Column("properties", Text),  # every JUnit testsuite property, as JSON
    Column("report", Text),  # revision 0002: the archived HTML report of this run
    Index("ix_runs_bench_started", "bench", "started_at"),
)

tests = Table(
    "tests", metadata,
    Column("id", Integer, primary_key=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("nodeid", Text, nullable=False),
    Column("area", String(100)),
    Column("outcome", String(20), nullable=False),
    Column("duration", Float),
    Column("attempt", Integer, nullable=False, default=1),
    Column("requirements", Text),  # space-separated requirement IDs
    Column("message", Text),
    Column("properties", Text),  # the testcase's other properties (wire statistics), as JSON
    Column("recorded_at", DateTime),
    UniqueConstraint("run_id", "nodeid", "attempt", name="uq_tests_run_nodeid_attempt"),
)

measurements = Table(
    "measurements", metadata,
    Column("id", Integer, primary_key=True),
    Column("test_id", Integer, ForeignKey("tests.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("name", String(200), nullable=False, index=True),
    Column("value", Float), Column("unit", String(50)),
    Column("low", Float), Column("high", Float),
    Column("outcome", String(10), nullable=False),
)

#: revision 0002: what a run's start had to repair first (the journal a killed run left)
recoveries = Table(
    "recoveries", metadata,
    Column("id", Integer, primary_key=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("note", Text, nullable=False),
)
