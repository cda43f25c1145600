"""SQLAlchemy 2.0 typed models: knowledge bases, CP types, CP points, and what replicas of the
service share besides them: each type's latest fit and the suggestions still pending.

A type's points are "the type's table" of the paper: rows of `cp_points` with its `type_pk`,
read in id order (cursor paging, CSV export). Counters on `cp_types` keep listing cheap.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    UniqueConstraint,
)
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeDecorator

NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

BigId = BigInteger().with_variant(Integer(), "sqlite")


def utcnow() -> datetime:
    return datetime.now(UTC)


class UtcDateTime(TypeDecorator[datetime]):
    """Timezone-aware UTC on the way out, whatever the backend keeps (SQLite keeps naive)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


class KnowledgeBaseRow(Base):
    __tablename__ = "knowledge_bases"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)


class TypeRow(Base):
    __tablename__ = "cp_types"
    __table_args__ = (UniqueConstraint("kb_id", "type_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    kb_id: Mapped[int] = mapped_column(ForeignKey("knowledge_bases.id", ondelete="CASCADE"))
    type_id: Mapped[str] = mapped_column(String(64))
    failure: Mapped[str] = mapped_column(String(128))
    decisions: Mapped[list[str]] = mapped_column(JSON)
    context: Mapped[list[str]] = mapped_column(JSON)
    graph: Mapped[dict[str, Any]] = mapped_column(JSON)
    space: Mapped[dict[str, Any]] = mapped_column(JSON)
    n_points: Mapped[int] = mapped_column(Integer, default=0)
    n_infeasible: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)


class PointRow(Base):
    __tablename__ = "cp_points"
    __table_args__ = (
        UniqueConstraint("kb_id", "key"),
        Index("ix_cp_points_type_pk_id", "type_pk", "id"),
    )

    id: Mapped[int] = mapped_column(BigId, primary_key=True, autoincrement=True)
    kb_id: Mapped[int] = mapped_column(ForeignKey("knowledge_bases.id", ondelete="CASCADE"))
    type_pk: Mapped[int] = mapped_column(ForeignKey("cp_types.id", ondelete="CASCADE"))
    x: Mapped[dict[str, Any]] = mapped_column(JSON)
    feasible: Mapped[bool] = mapped_column(Boolean)
    # The answer the first post of this point got, replayed when its key comes again.
    new_type: Mapped[bool] = mapped_column(Boolean, default=False)
    task: Mapped[str | None] = mapped_column(String(128))
    run: Mapped[str | None] = mapped_column(String(128))
    rollout: Mapped[int | None] = mapped_column(BigInteger)
    worker: Mapped[str | None] = mapped_column(String(128))
    time: Mapped[datetime | None] = mapped_column(UtcDateTime)
    extra: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    key: Mapped[str | None] = mapped_column(String(200))
    # SHA-256 of the keyed point's content: the same key with another point is a conflict.
    payload_hash: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)


class FitRow(Base):
    """A type's latest fit, so that one replica fits a version and the others load it
    (`server.surrogates.shared`). `n_fitted` is the version: the fit saw the type's first
    `n_fitted` points in id order."""

    __tablename__ = "cp_fits"

    type_pk: Mapped[int] = mapped_column(
        ForeignKey("cp_types.id", ondelete="CASCADE"), primary_key=True
    )
    n_fitted: Mapped[int] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(32))
    # `surrogate.snapshot.dump` of the predictor; the optimiser state for a warm start, as
    # `torch.save` writes it (None when the fit kind has none).
    predictor: Mapped[dict[str, Any]] = mapped_column(JSON)
    warm_state: Mapped[bytes | None] = mapped_column(LargeBinary)
    fit_seconds: Mapped[float] = mapped_column(Float)
    iterations: Mapped[int] = mapped_column(Integer)
    train_accuracy: Mapped[float | None] = mapped_column(Float)
    lengthscales: Mapped[list[float] | None] = mapped_column(JSON)
    fitted_by: Mapped[str] = mapped_column(String(128))
    fitted_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)


class PendingRow(Base):
    """A suggestion served but not yet answered by a point, kept where every replica sees it
    (`server.surrogates.pending_db`)."""

    __tablename__ = "cp_pending"
    __table_args__ = (Index("ix_cp_pending_kb_id_expires_at", "kb_id", "expires_at"),)

    id: Mapped[int] = mapped_column(BigId, primary_key=True, autoincrement=True)
    kb_id: Mapped[int] = mapped_column(ForeignKey("knowledge_bases.id", ondelete="CASCADE"))
    x: Mapped[dict[str, Any]] = mapped_column(JSON)
    # [[type_id, [[label, variable], ...]], ...], as `surrogate.pending.PendingEntry.binds`.
    binds: Mapped[list[Any]] = mapped_column(JSON)
    expires_at: Mapped[datetime] = mapped_column(UtcDateTime)


class BindingRow(Base):
    """A binding list a planner found for its task (`contract.bindings`)."""

    __tablename__ = "cp_bindings"
    __table_args__ = (
        Index("ix_cp_bindings_kb_id_skeleton_id", "kb_id", "skeleton", "id"),
        UniqueConstraint("kb_id", "key"),
    )

    id: Mapped[int] = mapped_column(BigId, primary_key=True, autoincrement=True)
    kb_id: Mapped[int] = mapped_column(ForeignKey("knowledge_bases.id", ondelete="CASCADE"))
    task: Mapped[str] = mapped_column(String(128))
    skeleton: Mapped[str] = mapped_column(String(128))
    run: Mapped[str | None] = mapped_column(String(128))
    rollout: Mapped[int | None] = mapped_column(BigInteger)
    bindings: Mapped[dict[str, Any]] = mapped_column(JSON)
    # Idempotency key (`contract.bindings.BindingIn.key`): the same key again stores nothing.
    key: Mapped[str | None] = mapped_column(String(200))
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=utcnow)
