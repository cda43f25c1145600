"""Found bindings: the binding list a planner found for its task, for the planners of the same
task on the knowledge base to try, and for users to see.

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-04
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# As in 0001, written out here: a migration must not change when the models do.
BigId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
UtcDateTime = sa.DateTime(timezone=True)

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "cp_bindings",
        sa.Column("id", BigId, autoincrement=True, nullable=False),
        sa.Column("kb_id", sa.Integer(), nullable=False),
        sa.Column("task", sa.String(length=128), nullable=False),
        sa.Column("skeleton", sa.String(length=128), nullable=False),
        sa.Column("run", sa.String(length=128), nullable=True),
        sa.Column("rollout", sa.BigInteger(), nullable=True),
        sa.Column("bindings", sa.JSON(), nullable=False),
        sa.Column("created_at", UtcDateTime, nullable=False),
        sa.ForeignKeyConstraint(
            ["kb_id"],
            ["knowledge_bases.id"],
            name=op.f("fk_cp_bindings_kb_id_knowledge_bases"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_cp_bindings")),
    )
    op.create_index("ix_cp_bindings_kb_id_skeleton_id", "cp_bindings", ["kb_id", "skeleton", "id"])


def downgrade() -> None:
    op.drop_index("ix_cp_bindings_kb_id_skeleton_id", table_name="cp_bindings")
    op.drop_table("cp_bindings")
