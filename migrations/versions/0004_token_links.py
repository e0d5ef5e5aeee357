"""API tokens linked to the browser session that issued them: `user_sessions.issued_by`, so
that signing out ends the tokens that session issued (app.people.sessions).  Sealed with the
row (app.store.row_seals) when set; rows from before keep their seals.

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column(
        "user_sessions",
        sa.Column("issued_by", sa.String(64), nullable=False, server_default=""),
    )
    op.create_index("ix_user_sessions_issued_by", "user_sessions", ["issued_by"])


def downgrade() -> None:
    op.drop_index("ix_user_sessions_issued_by", "user_sessions")
    with op.batch_alter_table("user_sessions") as batch:
        batch.drop_column("issued_by")
