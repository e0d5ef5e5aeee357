"""Every row that steers the station is sealed, with a counter for freshness: model
versions, the station's snapshot (with the audit record it follows), alarms, sessions and
settings get a MAC under the station's key and a version counter; users get the counter
(app.store.row_seals).

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-06
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

SEALED = ("model_versions", "stations", "alarms", "user_sessions", "settings")


def upgrade() -> None:
    op.add_column("users", sa.Column("seq", sa.Integer, nullable=False, server_default="0"))
    for table in SEALED:
        op.add_column(table, sa.Column("seq", sa.Integer, nullable=False, server_default="0"))
        op.add_column(table, sa.Column("mac", sa.String(64), nullable=False, server_default=""))
    op.add_column("stations", sa.Column("audit_id", sa.Integer, nullable=False, server_default="0"))
    op.add_column(
        "stations", sa.Column("audit_hash", sa.String(64), nullable=False, server_default="")
    )


def downgrade() -> None:
    with op.batch_alter_table("stations") as batch:
        batch.drop_column("audit_hash")
        batch.drop_column("audit_id")
    for table in (*SEALED, "users"):
        with op.batch_alter_table(table) as batch:
            batch.drop_column("seq")
            if table != "users":
                batch.drop_column("mac")
