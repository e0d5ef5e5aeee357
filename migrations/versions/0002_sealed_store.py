"""Sealed rows and revocable sessions: users and audit records get a MAC under the station's
key (kept outside the database, app.store.keys), and signed-in sessions and API tokens are
stored so that logout, a password change or disabling a user ends them.

Revision ID: 0002
Revises: 0001
Create Date: 2026-12-03
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("users", sa.Column("mac", sa.String(64), nullable=False, server_default=""))
    op.add_column("audit", sa.Column("mac", sa.String(64), nullable=False, server_default=""))
    op.create_table(
        "user_sessions",
        sa.Column("id", sa.String(64), primary_key=True),
        sa.Column("user_id", sa.Integer, sa.ForeignKey("users.id"), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("created_at", sa.Float, nullable=False),
        sa.Column("expires_at", sa.Float, nullable=False),
        sa.Column("revoked_at", sa.Float),
        sa.Column("revoked_why", sa.String(64), nullable=False, server_default=""),
        sa.Column("address", sa.String(64), nullable=False, server_default=""),
    )
    op.create_index("ix_user_sessions_user", "user_sessions", ["user_id"])


def downgrade() -> None:
    # audit.mac stays: the audit table is append-only, and dropping a column rebuilds it
    op.drop_table("user_sessions")
    with op.batch_alter_table("users") as batch:
        batch.drop_column("mac")
