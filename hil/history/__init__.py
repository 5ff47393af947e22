"""The run history: every session's run, tests and measurements in one store (SQLite in hil's state directory by
default, PostgreSQL for a lab), and what ``hil history`` and the HTML report read back from it.

* :mod:`~hil.history.schema` — the tables (SQLAlchemy Core), :mod:`~hil.history.migrations` their Alembic revisions;
* :mod:`~hil.history.store` — one store: open, migrate, write a run as it goes, read it back;
* :mod:`~hil.history.recorder` — the pytest plugin (entry point ``hil-history``) that records each session;
* :mod:`~hil.history.analysis` — compare, trend, first-pass yield, flaky tests, over what the store returns;
* :mod:`~hil.history.annotate` — the HTML report's history: sparklines, "since the last run", the previous report.

Recording never fails a run: a store that cannot be reached is reported once and the run is kept in a local spool
(:func:`~hil.history.config.spool_url`) that ``hil history sync`` uploads later.
"""
