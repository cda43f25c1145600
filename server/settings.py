"""Service settings: the one place that reads the environment (prefix `CPKB_`).

The default database is a SQLite file `cpkb.db` in the current directory, so that
`cpkb serve`, `cpkb plan` and `cpkb db upgrade` run from one directory share one knowledge
base without configuration; point `CPKB_DATABASE_URL` (or `--db`) elsewhere for anything else,
e.g. `postgresql+psycopg://user@host:5432/cpkb`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from client.models import MAX_NODES
from server.cpus import parse_cpu_list
from server.db import EngineOptions, SqliteSynchronous
from surrogate.config import AdditiveMode, SurrogateConfig

DEFAULT_DATABASE_URL = "sqlite:///cpkb.db"
DEFAULT_PORT = 8000
DEFAULT_GRAPH_NODES = 8192


class Settings(BaseSettings):
    """Every knob of the service; each field `foo` is read from `CPKB_FOO`."""

    model_config = SettingsConfigDict(env_prefix="CPKB_", extra="ignore")

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

    # Surrogates (server.surrogates): fits run in a child process unless false; see EngineConfig.
    # Disabled, the service stores and serves points only (suggest / predict answer 503).
    surrogate_enabled: bool = True
    surrogate_fit_process: bool = True
    # How far below the priority it was started with the service runs (its fits, mostly): on a
    # machine it shares with planners (the embedded service of `cpkb plan` and `cpkb bench`)
    # they take the cores first and the fits the cycles left; alone on a machine, no change.
    surrogate_nice: int = Field(default=5, ge=0, le=19)
    # The cores the service, its threads and its fit processes run on (`1`, `1-3`, `0,2`;
    # Linux): the embedded service of `cpkb plan` and `cpkb bench` gets those its planners
    # leave (server.cpus). Unset: any core.
    cpu_cores: str | None = None
    surrogate_max_inducing: int = Field(default=SurrogateConfig.max_inducing, ge=8, le=1024)
    # A fit trains on at most this many of a type's points (0: all); see SurrogateConfig.
    surrogate_max_fit_points: int = Field(default=SurrogateConfig.max_fit_points, ge=0)
    # A new type gets a short fit in the service's process up to this many points (0: never).
    surrogate_instant_fit_points: int = Field(
        default=SurrogateConfig.instant_fit_points, ge=0, le=2000
    )
    surrogate_instant_fit_iters: int = Field(
        default=SurrogateConfig.instant_fit_iters, ge=1, le=1000
    )
    # ... and a type whose fit lags this many times behind its points (0: first models only).
    surrogate_instant_refit_factor: float = Field(
        default=SurrogateConfig.instant_refit_factor, ge=0.0, le=100.0
    )
    # Kernel terms of one decision's inputs beside the main kernel: see surrogate.additive.
    surrogate_additive: AdditiveMode = SurrogateConfig.additive
    # SMOTE a type's minority class before a fit (the paper), or fit its points as they are.
    surrogate_balance_classes: bool = SurrogateConfig.balance_classes
    # A type in use loads its new points when they are older than this (one indexed query).
    surrogate_refresh_s: float = Field(default=SurrogateConfig.refresh_s, ge=0)
    surrogate_pending_ttl_s: float = Field(default=SurrogateConfig.pending_ttl_s, ge=0)
    surrogate_prefit_types: int = Field(default=SurrogateConfig.prefit_types, ge=0)
    surrogate_pop_size: int = Field(default=SurrogateConfig.pop_size, ge=4, le=1000)
    surrogate_generations: int = Field(default=SurrogateConfig.generations, ge=0, le=1000)
    surrogate_raw_samples: int = Field(default=SurrogateConfig.raw_samples, ge=1, le=100_000)
    # The MPF answer's spread: see surrogate.config.SurrogateConfig.
    surrogate_mpf_margin: float = Field(default=SurrogateConfig.mpf_margin, ge=0.0, le=1.0)
    surrogate_mpf_margin_abs: float = Field(default=SurrogateConfig.mpf_margin_abs, ge=0.0, le=1.0)

    # Replicas on one database (server.surrogates.shared, .pending_db): fits are stored there
    # and loaded by the other replicas; the pending book lives there (`auto`: on PostgreSQL,
    # the one backend several replicas share; in memory on SQLite). The name marks the fits
    # this replica stored (default host:pid).
    surrogate_share_fits: bool = True
    surrogate_pending_store: Literal["auto", "memory", "database"] = "auto"
    surrogate_claim_retry_s: float = Field(default=1.0, gt=0, le=60)
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
    """The surrogate settings this environment sets away from their defaults: a bench records
    them with its results, since its embedded service runs with them."""
    here, default = Settings(), Settings.model_construct()
    return {
        name: getattr(here, name)
        for name in Settings.model_fields
        if name.startswith("surrogate_") and getattr(here, name) != getattr(default, name)
    }
