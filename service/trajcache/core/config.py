"""Service settings, read from `TRAJCACHE_*` environment variables."""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Literal, Self

import platformdirs
from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from trajcache.core.planners import PLANNER_NAMES

MIB = 1024 * 1024
MAX_PAGE_SIZE = 1000  # the `limit` maximum the API document states; max_page_size may lower it


class Settings(BaseSettings):
    """All configuration of the service; every field is documented for the README table."""

    model_config = SettingsConfigDict(
        env_prefix="TRAJCACHE_", extra="ignore", validate_default=True
    )

    # Database
    data_dir: Path | None = Field(
        default=None,
        description="Directory of a relative SQLite path in database_url, whichever directory "
        "a command runs in (created with the database). Unset: the user's data directory, "
        "`~/.local/share/trajcache` on Linux.",
    )
    database_url: str = Field(
        default="sqlite:///trajcache.db",
        description="SQLAlchemy URL of the cache database (SQLite file, or PostgreSQL for a "
        "fleet; `postgresql://` is read as `postgresql+psycopg://`). A relative SQLite path is "
        "in data_dir.",
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
    certificates: bool = Field(default=True, description="Keep what each valid verdict proved "
        "with its trajectory: later validations prove only new ends and objects.")  # fmt: skip
    certificate_audit: bool = Field(default=False, description="Debugging: prove every verdict "
        "a certificate shortened again in full; fail on any disagreement.")  # fmt: skip
    index_sync_interval_s: float = Field(
        default=0.0,
        ge=0,
        description="Seconds between checks of the database for other replicas' writes "
        "(0 = check before every plan).",
    )
    require_scene: bool = Field(default=False, description="Refuse to plan for a robot that "
        "never uploaded a scene (409; MoveIt: -22) instead of checking its plans for "
        "self-collision only, with a warning.")  # fmt: skip

    # Planning and workers
    worker_backend: Literal["local", "celery", "none"] = Field(
        default="local",
        description="Where fallback planning runs: a local process pool, Celery workers, or "
        "nowhere ('none': a request no cached trajectory serves gets status 'miss').",
    )
    worker_processes: int = Field(
        default=2, ge=1, description="Size of the local planning process pool."
    )
    worker_prestart: bool = Field(
        default=True,
        description="Start the planner pool with the service, so the first miss does not wait "
        "for workers to start (off: start it on the first miss).",
    )
    request_threads: int = Field(
        default=12,
        ge=1,
        le=1000,
        description="Threads answering requests per server process. Few beat many: more only "
        "queue for the interpreter lock. A request waiting for the planner holds one for up to "
        "its budget, so allow for the misses expected at once.",
    )
    plan_budget_s: float = Field(
        default=2.0, gt=0, description="Default planner time budget per request (s)."
    )
    plan_budget_max_s: float = Field(
        default=30.0, gt=0, description="Largest planner time budget a request may ask for (s)."
    )
    default_planner: str = Field(
        default="compiled", min_length=1, description="Planner used when a request names none."
    )
    pose_goal_threshold: float = Field(default=1.0, gt=0, description="How far (rad, on "
        "every joint) a cached path's end may lie from a pose goal's state for the lookup "
        "(its start: the request's threshold).")  # fmt: skip
    repair_budget_s: float = Field(default=0.25, ge=0, description="Planner budget (s) to mend "
        "a rejected cached path's failing stretch before planning anew (0: off).")  # fmt: skip
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
        default="redis://127.0.0.1:6379/1", description="Celery result backend URL (celery only)."
    )
    celery_queue: str = Field(
        default="plan", min_length=1, description="Celery queue of planning tasks and workers."
    )

    # Timing (time-optimal or jerk-limited) of answered trajectories
    timing_joint_acceleration: float = Field(
        default=5.0,
        gt=0,
        description="Acceleration limit of an arm joint whose model was registered without one "
        "(rad/s², m/s² for prismatic joints).",
    )
    timing_joint_jerk: float = Field(
        default=50.0,
        gt=0,
        description="Jerk limit of an arm joint whose model was registered without one "
        "(rad/s³, m/s³ for prismatic joints; jerk-limited timing only).",
    )
    timing_base_velocity: tuple[float, float, float] = Field(
        default=(0.5, 0.5, 1.0),
        description="Velocity limits of a planar base: x, y (m/s), θ (rad/s); JSON list.",
    )
    timing_base_acceleration: tuple[float, float, float] = Field(
        default=(0.5, 0.5, 1.0),
        description="Acceleration limits of a planar base: x, y (m/s²), θ (rad/s²); JSON list.",
    )
    timing_base_jerk: tuple[float, float, float] = Field(
        default=(2.0, 2.0, 4.0),
        description="Jerk limits of a planar base: x, y (m/s³), θ (rad/s³); JSON list.",
    )
    timing_max_points: int = Field(
        default=10_000, ge=2, description="Most points in one timed trajectory of an answer."
    )

    # Request limits
    max_body_bytes: int = Field(
        default=16 * MIB, ge=1, description="Largest accepted request body (bytes)."
    )
    max_urdf_bytes: int = Field(default=2 * MIB, ge=1, description="Largest accepted URDF (bytes).")
    max_archive_bytes: int = Field(
        default=64 * MIB, ge=1, description="Largest accepted mesh archive (bytes)."
    )
    max_archive_entries: int = Field(default=1000, ge=1, description="Most files in an archive.")
    max_scene_objects: int = Field(
        default=2000, ge=1, description="Most collision objects accepted in a scene."
    )
    max_scene_extent_m: float = Field(
        default=1000.0,
        gt=0,
        le=1e6,
        description="How far (m) a scene object may reach from the origin of its frame (the "
        "world, or an attached object's link): its position's distance plus its size.",
    )
    max_trajectory_states: int = Field(
        default=5000, ge=2, description="Most states accepted in one trajectory."
    )
    max_page_size: int = Field(
        default=MAX_PAGE_SIZE,
        ge=1,
        le=MAX_PAGE_SIZE,
        description=f"Largest page of a list endpoint (at most {MAX_PAGE_SIZE}).",
    )

    # Security
    auth_mode: Literal["auto", "on", "off"] = Field(
        default="auto",
        description="API key checks: `on`, `off`, or `auto` (on when `host` is not a loopback "
        "address or once any key has been created, even if all are revoked since).",
    )
    auth_cache_ttl_s: float = Field(
        default=5.0,
        ge=0,
        description="Seconds a verified API key is trusted without asking the database "
        "(a revoked key stops working within this time).",
    )

    # Pre-seeding (seed jobs), candidate ranking and eviction
    seed_concurrency: int = Field(
        default=2,
        ge=1,
        le=64,
        description="Plan requests one seed job keeps in flight (a job may ask for fewer).",
    )
    seed_max_running_jobs: int = Field(
        default=1, ge=1, description="Seed jobs one service process runs at the same time."
    )
    seed_max_scenes: int = Field(
        default=500, ge=1, description="Most scenes (or scene variants) in one seed job."
    )
    seed_max_queries: int = Field(
        default=100_000,
        ge=1,
        description="Most plan requests in one seed job (queries × scenes, or workload calls).",
    )
    seed_lease_s: float = Field(
        default=30.0,
        gt=0,
        description="How long a replica's claim on a running seed job lasts without a "
        "heartbeat; a job whose claim ran out (its replica stopped) is resumed by another.",
    )
    seed_heartbeat_s: float = Field(
        default=2.0,
        gt=0,
        description="Seconds between a running seed job's progress writes (which renew its "
        "claim and notice a cancel from another replica).",
    )
    seed_poll_interval_s: float = Field(
        default=5.0,
        gt=0,
        description="Seconds between a replica's looks for queued or orphaned seed jobs.",
    )
    seed_scene_retention_days: float = Field(
        default=7.0, ge=0, description="Days finished seed jobs keep unused scenes (0: keep them)."
    )
    ranking_pool: int = Field(
        default=10,
        ge=1,
        le=100,
        description="Relevant candidates (within the lookup threshold, nearest first) that "
        "ranking re-orders before the best max_candidates are tried.",
    )
    ranking_env_enabled: bool = Field(
        default=True,
        description="Try candidates whose recorded environment values are nearest to the "
        "requesting scene's first (environment-dependent indexing).",
    )
    ranking_env_weight: float = Field(
        default=0.05,
        ge=0,
        description="Distance added per unit of environment-value difference (summed over the "
        "request's values, each capped at ranking_env_cap).",
    )
    ranking_env_cap: float = Field(
        default=1.0,
        gt=0,
        description="Largest difference one environment value counts for; a value the "
        "candidate did not record counts as this.",
    )
    ranking_real_enabled: bool = Field(
        default=True, description="Prefer candidates recently validated on a real robot."
    )
    ranking_real_bonus: float = Field(
        default=0.02,
        ge=0,
        description="Distance taken off a candidate validated on a real robot just now; it "
        "fades linearly to 0 over ranking_real_window_s.",
    )
    ranking_real_window_s: float = Field(
        default=30 * 24 * 3600.0,
        gt=0,
        description="How long a real-robot validation keeps counting for a candidate (s).",
    )
    ranking_failure_enabled: bool = Field(
        default=True,
        description="Try candidates that failed validation repeatedly in a row last.",
    )
    ranking_failure_demote_after: int = Field(
        default=3,
        ge=1,
        description="Consecutive validation failures after which a candidate is tried last.",
    )
    ranking_facts_ttl_s: float = Field(default=30.0, gt=0, description="Seconds a replica "
        "trusts the ranking facts it read (others' bookkeeping shows up within them).")  # fmt: skip
    cache_max_per_model: int = Field(default=0, ge=0, description="Most trajectories kept per "
        "robot model; beyond it the eviction policy deletes the rest (0 = no cap).")  # fmt: skip
    eviction_policy: Literal["lru", "least_hit"] = Field(default="lru", description="What "
        "eviction deletes first: `lru` (least recently used, never-used ones by creation time) "
        "or `least_hit` (fewest hits, then least recently used).")  # fmt: skip
    eviction_interval_s: float = Field(default=300.0, ge=0, description="Seconds between "
        "automatic evictions when cache_max_per_model is set (0 = only on demand: `trajcache "
        "prune`, POST /v1/admin/prune).")  # fmt: skip
    quality_backfill_per_s: float = Field(
        default=50.0, ge=0, description="Background quality and end-pose rows per second (0: off)."
    )
    commit_log_retention_s: float = Field(default=86400.0, ge=600, description="Seconds the "
        "trajectory commit log and the tombstones of deleted trajectories are kept for "
        "replicas' syncs; a replica that synced less recently reloads its indexes.")  # fmt: skip

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

    @field_validator("data_dir")
    @classmethod
    def _absolute_data_dir(cls, value: Path | None) -> Path | None:
        if value is None:
            return None
        value = value.expanduser()
        if not value.is_absolute():
            raise ValueError(f"data_dir must be an absolute path, got {str(value)!r}")
        return value

    @model_validator(mode="after")
    def _sqlite_in_data_dir(self) -> Self:
        """A relative SQLite path names a file in data_dir, not in the current directory."""
        if self.data_dir is None:
            self.data_dir = Path(platformdirs.user_data_dir("trajcache", appauthor=False))
        from sqlalchemy.engine import make_url  # here: commands that read no database stay light
        from sqlalchemy.exc import ArgumentError

        try:
            url = make_url(self.database_url)
        except ArgumentError:
            raise ValueError(f"database_url {self.database_url!r} is not a database URL") from None
        path = url.database
        if url.get_backend_name() != "sqlite" or not path or path == ":memory:":
            return self
        if path.startswith("file:") or Path(path).is_absolute():
            return self
        located = url.set(database=str(self.data_dir / path))
        self.database_url = located.render_as_string(hide_password=False)
        return self

    @field_validator("default_planner")
    @classmethod
    def _known_planner(cls, value: str) -> str:
        key = value.strip().lower()
        if key not in PLANNER_NAMES:
            raise ValueError(f"unknown planner {value!r}; use one of {', '.join(PLANNER_NAMES)}")
        return key

    @field_validator("timing_base_velocity", "timing_base_acceleration", "timing_base_jerk")
    @classmethod
    def _positive_limits(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(math.isfinite(v) and v > 0 for v in value):
            raise ValueError(f"base limits must be three finite values > 0, got {list(value)}")
        return value

    @field_validator("log_level", mode="before")
    @classmethod
    def _lower_log_level(cls, value: object) -> object:
        return value.strip().lower() if isinstance(value, str) else value  # fmt: skip

    @model_validator(mode="after")
    def _check_limits(self) -> Self:
        if self.seed_heartbeat_s >= self.seed_lease_s:
            raise ValueError("seed_heartbeat_s must be shorter than seed_lease_s")
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
