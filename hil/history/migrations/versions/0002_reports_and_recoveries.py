"""Each run's archived HTML report (the next report links it) and the recovery its start needed.

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"


def upgrade() -> None:
    op.add_column("runs", sa.Column("report", sa.Text))
    op.create_table(
        "recoveries",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
        sa.Column("note", sa.Text, nullable=False),
    )
    op.create_index("ix_recoveries_run_id", "recoveries", ["run_id"])


def downgrade() -> None:
    op.drop_table("recoveries")
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("report")
