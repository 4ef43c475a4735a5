"""Service settings, read from `TRAJCACHE_*` environment variables."""

from __future__ import annotations

from functools import lru_cache
from typing import Literal, Self

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

MIB = 1024 * 1024


class Settings(BaseSettings):
    """All configuration of the service; every field is documented for the README table."""

    model_config = SettingsConfigDict(
        env_prefix="TRAJCACHE_",
        extra="ignore",
        validate_default=True,
    )

    # Database
    database_url: str = Field(
        default="sqlite:///./trajcache.db",
        description="SQLAlchemy URL of the cache database (SQLite file, or PostgreSQL for a "
        "fleet; `postgresql://` is read as `postgresql+psycopg://`).",
    )
    db_pool_size: int = Field(
        default=10, ge=1, description="Connection pool size per service process."
    )

    # HTTP server
    host: str = Field(default="127.0.0.1", description="Address the HTTP server binds to.")
    port: int = Field(default=8000, ge=1, le=65535, description="Port the HTTP server binds to.")
    log_level: Literal["critical", "error", "warning", "info", "debug", "trace"] = Field(
        default="info", description="Log level (critical, error, warning, info, debug, trace)."
    )

    # Cache lookup
    lookup_threshold: float = Field(
        default=0.2,
        gt=0,
        description="Default distance below which a cached start/goal is relevant (paper, §3).",
    )
    lookup_threshold_max: float = Field(
        default=0.5, gt=0, description="Largest lookup threshold a request may ask for."
    )
    max_candidates: int = Field(
        default=3, ge=1, description="Default number of cached candidates tried per request."
    )
    max_candidates_limit: int = Field(
        default=10, ge=1, description="Largest number of candidates a request may ask for."
    )

    # Validation
    step_position_m: float = Field(
        default=0.04, gt=0, description="Largest base translation between validated samples (m)."
    )
    step_orientation_rad: float = Field(
        default=0.04, gt=0, description="Largest base rotation between validated samples (rad)."
    )
    step_joint_rad: float = Field(
        default=0.035, gt=0, description="Largest joint motion between validated samples (rad)."
    )
    certified_validation: bool = Field(
        default=True,
        description="Pad link geometry by its largest motion between samples so no collision "
        "can hide between them.",
    )
    index_sync_interval_s: float = Field(
        default=0.0,
        ge=0,
        description="Seconds between checks of the database for other replicas' writes "
        "(0 = check before every plan).",
    )

    # Planning and workers
    worker_backend: Literal["local", "celery"] = Field(
        default="local",
        description="Where fallback planning runs: a local process pool or Celery workers.",
    )
    worker_processes: int = Field(
        default=2, ge=1, description="Size of the local planning process pool."
    )
    plan_budget_s: float = Field(
        default=2.0, gt=0, description="Default planner time budget per request (s)."
    )
    plan_budget_max_s: float = Field(
        default=30.0, gt=0, description="Largest planner time budget a request may ask for (s)."
    )
    default_planner: str = Field(
        default="rrtconnect", min_length=1, description="Planner used when a request names none."
    )
    negative_cache_ttl_s: float = Field(
        default=30.0,
        ge=0,
        description="Seconds a failed planning query is remembered and answered without "
        "replanning (0 = off).",
    )
    celery_broker_url: str = Field(
        default="redis://127.0.0.1:6379/0", description="Celery broker URL (celery backend only)."
    )
    celery_result_backend: str = Field(
        default="redis://127.0.0.1:6379/1",
        description="Celery result backend URL (celery backend only).",
    )

    # Request limits
    max_body_bytes: int = Field(
        default=16 * MIB, ge=1, description="Largest accepted request body (bytes)."
    )
    max_urdf_bytes: int = Field(default=2 * MIB, ge=1, description="Largest accepted URDF (bytes).")
    max_archive_bytes: int = Field(
        default=64 * MIB, ge=1, description="Largest accepted mesh archive (bytes)."
    )
    max_archive_entries: int = Field(
        default=1000, ge=1, description="Most files accepted in a mesh archive."
    )
    max_scene_objects: int = Field(
        default=2000, ge=1, description="Most collision objects accepted in a scene."
    )
    max_trajectory_states: int = Field(
        default=5000, ge=2, description="Most states accepted in one trajectory."
    )
    max_page_size: int = Field(default=1000, ge=1, description="Largest page of a list endpoint.")

    # Security
    auth_mode: Literal["auto", "on", "off"] = Field(
        default="auto",
        description="API key checks: `on`, `off`, or `auto` (on once any key exists).",
    )

    @field_validator("database_url")
    @classmethod
    def _normalise_database_url(cls, value: str) -> str:
        value = value.strip()
        if not value:
            raise ValueError("database_url must not be empty")
        for prefix in ("postgresql://", "postgres://"):
            if value.startswith(prefix):
                return "postgresql+psycopg://" + value[len(prefix) :]
        return value

    @field_validator("log_level", mode="before")
    @classmethod
    def _lower_log_level(cls, value: object) -> object:
        return value.strip().lower() if isinstance(value, str) else value

    @model_validator(mode="after")
    def _check_limits(self) -> Self:
        if self.lookup_threshold > self.lookup_threshold_max:
            raise ValueError("lookup_threshold must not exceed lookup_threshold_max")
        if self.max_candidates > self.max_candidates_limit:
            raise ValueError("max_candidates must not exceed max_candidates_limit")
        if self.plan_budget_s > self.plan_budget_max_s:
            raise ValueError("plan_budget_s must not exceed plan_budget_max_s")
        return self


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return Settings()
