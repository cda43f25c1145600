"""A found binding's idempotency key: a client re-sending a binding whose answer it lost stores
it once, as for points.

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-07
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Nullable: bindings stored before this revision (and by older clients) have no key.
    with op.batch_alter_table("cp_bindings") as batch:
        batch.add_column(sa.Column("key", sa.String(length=200), nullable=True))
        batch.create_unique_constraint(op.f("uq_cp_bindings_kb_id_key"), ["kb_id", "key"])


def downgrade() -> None:
    with op.batch_alter_table("cp_bindings") as batch:
        batch.drop_constraint(op.f("uq_cp_bindings_kb_id_key"), type_="unique")
        batch.drop_column("key")
