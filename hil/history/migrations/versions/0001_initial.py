"""The first schema: runs, their tests, the tests' measurements.

Revision ID: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None


def upgrade() -> None:
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("uuid", sa.String(36), nullable=False, unique=True),
        sa.Column("bench", sa.String(200), nullable=False),
        sa.Column("target", sa.Text), sa.Column("transport", sa.String(100)),
        sa.Column("plc", sa.Text), sa.Column("rtc_chip", sa.String(200)),
        sa.Column("profile", sa.Text), sa.Column("profile_sha256", sa.String(64)),
        sa.Column("suites_commit", sa.String(100)), sa.Column("harness_version", sa.String(50)),
        sa.Column("operator", sa.String(200)), sa.Column("station", sa.String(200)),
        sa.Column("lab_place", sa.String(200)),
        sa.Column("host", sa.String(200)), sa.Column("pid", sa.Integer),
        sa.Column("started_at", sa.DateTime, nullable=False),
        sa.Column("ended_at", sa.DateTime),
        sa.Column("finished", sa.Boolean, nullable=False),
        sa.Column("verdict", sa.String(40), nullable=False),
        sa.Column("stopped", sa.Text), sa.Column("not_run", sa.Integer), sa.Column("plc_restored", sa.Text),
        sa.Column("properties", sa.Text),
    )
    op.create_index("ix_runs_bench_started", "runs", ["bench", "started_at"])
    op.create_table(
        "tests",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
        sa.Column("nodeid", sa.Text, nullable=False),
        sa.Column("area", sa.String(100)),
        sa.Column("outcome", sa.String(20), nullable=False),
        sa.Column("duration", sa.Float),
        sa.Column("attempt", sa.Integer, nullable=False),
        sa.Column("requirements", sa.Text),
        sa.Column("message", sa.Text),
        sa.Column("properties", sa.Text),
        sa.Column("recorded_at", sa.DateTime),
        sa.UniqueConstraint("run_id", "nodeid", "attempt", name="uq_tests_run_nodeid_attempt"),
    )
    op.create_index("ix_tests_run_id", "tests", ["run_id"])
    op.create_table(
        "measurements",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("test_id", sa.Integer, sa.ForeignKey("tests.id", ondelete="CASCADE"), nullable=False),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("value", sa.Float), sa.Column("unit", sa.String(50)),
        sa.Column("low", sa.Float), sa.Column("high", sa.Float),
        sa.Column("outcome", sa.String(10), nullable=False),
    )
    for column in ("test_id", "run_id", "name"):
        op.create_index(f"ix_measurements_{column}", "measurements", [column])


def downgrade() -> None:
    op.drop_table("measurements")
    op.drop_table("tests")
    op.drop_table("runs")
