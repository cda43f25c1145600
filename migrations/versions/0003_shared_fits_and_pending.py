"""What replicas of the service share besides the points: each type's latest fit (so that one
replica fits a version and the others load it) and the suggestions still pending (so that
planners asking different replicas are pushed apart).

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-02
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

# As in 0001, written out here: a migration must not change when the models do.
BigId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
UtcDateTime = sa.DateTime(timezone=True)

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "cp_fits",
        sa.Column("type_pk", sa.Integer(), nullable=False),
        sa.Column("n_fitted", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(length=32), nullable=False),
        sa.Column("predictor", sa.JSON(), nullable=False),
        sa.Column("warm_state", sa.LargeBinary(), nullable=True),
        sa.Column("fit_seconds", sa.Float(), nullable=False),
        sa.Column("iterations", sa.Integer(), nullable=False),
        sa.Column("train_accuracy", sa.Float(), nullable=True),
        sa.Column("lengthscales", sa.JSON(), nullable=True),
        sa.Column("fitted_by", sa.String(length=128), nullable=False),
        sa.Column("fitted_at", UtcDateTime, nullable=False),
        sa.ForeignKeyConstraint(
            ["type_pk"],
            ["cp_types.id"],
            name=op.f("fk_cp_fits_type_pk_cp_types"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("type_pk", name=op.f("pk_cp_fits")),
    )
    op.create_table(
        "cp_pending",
        sa.Column("id", BigId, autoincrement=True, nullable=False),
        sa.Column("kb_id", sa.Integer(), nullable=False),
        sa.Column("x", sa.JSON(), nullable=False),
        sa.Column("binds", sa.JSON(), nullable=False),
        sa.Column("owner", sa.String(length=128), nullable=True),
        sa.Column("expires_at", UtcDateTime, nullable=False),
        sa.ForeignKeyConstraint(
            ["kb_id"],
            ["knowledge_bases.id"],
            name=op.f("fk_cp_pending_kb_id_knowledge_bases"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_cp_pending")),
    )
    op.create_index("ix_cp_pending_kb_id_expires_at", "cp_pending", ["kb_id", "expires_at"])


def downgrade() -> None:
    op.drop_index("ix_cp_pending_kb_id_expires_at", table_name="cp_pending")
    op.drop_table("cp_pending")
    op.drop_table("cp_fits")
