"""Service settings: the one place that reads the environment (prefix `CPKB_`).

The default database is a SQLite file `cpkb.db` in the current directory, so that
`cpkb serve`, `cpkb plan` and `cpkb db upgrade` run from one directory share one knowledge
base without configuration; point `CPKB_DATABASE_URL` (or `--db`) elsewhere for anything else,
e.g. `postgresql+psycopg://user@host:5432/cpkb`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from contract.models import MAX_NODES
from server.cpus import parse_cpu_list
from server.db import EngineOptions, SqliteSynchronous
from surrogate.config import SurrogateConfig

DEFAULT_DATABASE_URL = "sqlite:///cpkb.db"
DEFAULT_PORT = 8000
DEFAULT_GRAPH_NODES = 8192


class ServiceSurrogateConfig(SurrogateConfig):
    """The surrogate knobs, and how this service runs its fits."""

    enabled: bool = True
    """Off, the service stores and serves points only (suggest and predict answer 503)."""
    fit_process: bool = True
    """Fits run in a child process; off, in a thread of the service's own process."""
    nice: int = Field(default=5, ge=0, le=19)
    """How far below the priority it was started with the service runs (its fits, mostly): on
    a machine it shares with planners (the embedded service of `cpkb plan` and `cpkb bench`)
    they take the cores first and the fits the cycles left; alone on a machine, no change."""
    share_fits: bool = True
    """Replicas on one database (server.surrogates.shared): fits are stored there and loaded
    by the other replicas."""
    pending_store: Literal["auto", "memory", "database"] = "auto"
    """Where the book of pending suggestions lives (server.surrogates.pending_db); `auto`: in
    the database on PostgreSQL, the one backend several replicas share, in memory on SQLite."""
    claim_retry_s: float = Field(default=1.0, gt=0, le=60)
    """How long a replica waits before looking again at a type another replica is fitting."""


class Settings(BaseSettings):
    """Every knob of the service; each field `foo` is read from `CPKB_FOO`, each field `bar`
    of a nested group `group` from `CPKB_GROUP__BAR`."""

    model_config = SettingsConfigDict(env_prefix="CPKB_", env_nested_delimiter="__", extra="ignore")

    database_url: str = DEFAULT_DATABASE_URL
    host: str = "127.0.0.1"
    port: int = Field(default=DEFAULT_PORT, ge=0, le=65535)
    # Where the CLI and clients find a running service (`cpkb kb list`, `cpkb types`).
    url: str = f"http://127.0.0.1:{DEFAULT_PORT}"

    # Limits: a request body, points per page.
    max_body_bytes: int = Field(default=32 * 1024 * 1024, ge=1024)
    default_page_size: int = Field(default=100, ge=1)
    max_page_size: int = Field(default=1000, ge=1)
    # The nodes of the distinct graphs one request (a match, a post) may have hashed into types:
    # hashing costs about 25 ms per 64-node graph, and a match is open to anyone (413 beyond).
    # A planner's match of 500 graphs of its task stays well within.
    max_request_graph_nodes: int = Field(default=DEFAULT_GRAPH_NODES, ge=MAX_NODES)

    # Database behaviour (server.db.EngineOptions says what each does).
    sqlite_busy_timeout_ms: int = Field(default=EngineOptions.busy_timeout_ms, ge=0)
    sqlite_synchronous: SqliteSynchronous = EngineOptions.sqlite_synchronous
    pool_size: int = Field(default=EngineOptions.pool_size, ge=1)
    pg_lock_timeout_ms: int = Field(default=EngineOptions.pg_lock_timeout_ms, ge=0)
    pg_idle_in_transaction_timeout_ms: int = Field(
        default=EngineOptions.pg_idle_in_transaction_timeout_ms, ge=0
    )

    # Access (used by server.security).
    token: SecretStr | None = None
    tokens_file: Path | None = None
    auth_reads: bool = False
    cors_origins: list[str] = Field(default_factory=list)

    log_level: str = "info"

    # The surrogates (server.surrogates): `CPKB_SURROGATE__<KNOB>`, and
    # `CPKB_SURROGATE__OPTIMIZER__<KNOB>` for the MPF maximiser (surrogate.config).
    surrogate: ServiceSurrogateConfig = ServiceSurrogateConfig()
    # The cores the service, its threads and its fit processes run on (`1`, `1-3`, `0,2`;
    # Linux): the embedded service of `cpkb plan` and `cpkb bench` gets those its planners
    # leave (server.cpus). Unset: any core.
    cpu_cores: str | None = None
    # The name that marks the fits this replica stores (default host:pid).
    replica_name: str | None = Field(default=None, min_length=1, max_length=128)

    def engine_options(self) -> EngineOptions:
        return EngineOptions(
            busy_timeout_ms=self.sqlite_busy_timeout_ms,
            pool_size=self.pool_size,
            sqlite_synchronous=self.sqlite_synchronous,
            pg_lock_timeout_ms=self.pg_lock_timeout_ms,
            pg_idle_in_transaction_timeout_ms=self.pg_idle_in_transaction_timeout_ms,
            application_name=self.replica_name or "cpkb",
        )

    @field_validator("cpu_cores")
    @classmethod
    def _cpu_list(cls, value: str | None) -> str | None:
        if value is not None:
            parse_cpu_list(value)
        return value


def surrogate_overrides() -> dict[str, object]:
    """The surrogate settings this environment sets away from their defaults, by dotted name
    (`surrogate.optimizer.generations`): a bench records them with its results, since its
    embedded service runs with them."""
    return _changed("surrogate", Settings().surrogate, ServiceSurrogateConfig())


def _changed(prefix: str, here: BaseModel, default: BaseModel) -> dict[str, object]:
    changed: dict[str, object] = {}
    for name in type(here).model_fields:
        value, base = getattr(here, name), getattr(default, name)
        if isinstance(value, BaseModel) and isinstance(base, BaseModel):
            changed |= _changed(f"{prefix}.{name}", value, base)
        elif value != base:
            changed[f"{prefix}.{name}"] = value
    return changed
