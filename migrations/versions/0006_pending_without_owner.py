"""The pending book no longer keeps an owner per entry: the pending exchange between planners
(`knowledge.live_pending`) was retired, and with it the entries planners reported under their
run's name. Reported entries left in the table are dropped with the column (they expire within
seconds anyway).

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-07
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006"
down_revision: str | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.execute(sa.text("DELETE FROM cp_pending WHERE owner IS NOT NULL"))
    with op.batch_alter_table("cp_pending") as batch:
        batch.drop_column("owner")


def downgrade() -> None:
    with op.batch_alter_table("cp_pending") as batch:
        batch.add_column(sa.Column("owner", sa.String(length=128), nullable=True))
