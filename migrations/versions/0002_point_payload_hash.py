"""A point's payload hash: an idempotency key names one request, so a different point under a
stored key is refused (409) instead of answered with the first point's result.

Revision ID: 0002
Revises: 0001
Create Date: 2026-12-02
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Nullable: points stored before this revision have no hash, and any payload replays them.
    op.add_column("cp_points", sa.Column("payload_hash", sa.String(length=64), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("cp_points") as batch:
        batch.drop_column("payload_hash")
