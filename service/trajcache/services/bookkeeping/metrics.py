"""Prometheus metrics, served at `GET /metrics` (`api.prometheus`): plan requests, step
latencies, cache size, planner pool; one module holds every metric of the service, the sampler
that copies the planner pool's counters into them and the collector of the cache size.

Every answered plan request is counted, a robot's and a seed job's alike (label `requester`:
`robot` or `seed_job`), where its plan event is recorded (`outcomes.record_outcome`), and so is
every refused one (`refusals`): the counts agree with `/v1/stats`.

One process keeps its metrics in the default registry. Several uvicorn workers are one service
only if their metrics are merged: when `PROMETHEUS_MULTIPROC_DIR` is set, every process writes
its samples to files there and `/metrics`, whichever worker answers, merges all of them
(`MultiProcessCollector`). `trajcache serve --workers N` (N > 1) sets the variable before the
workers start, to a fresh temporary directory, or empties the directory it already names
(`core.prometheus_dir`); set it yourself (e.g. to a volume) to keep it elsewhere. It must be
set before this module is imported, which is why the command line does it, not the app; run
`uvicorn --workers N` directly only with the variable set to an empty directory.

The cache size per model is counted in the database at scrape time; the planner pool's queue
depth and failures are sampled every second by each process (queue depths of live workers add
up; a worker that exits removes its own).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Iterator, Mapping

import sqlalchemy as sa
from prometheus_client import (
    REGISTRY,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    generate_latest,
    multiprocess,
)
from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from trajcache.core.prometheus_dir import MULTIPROC_ENV
from trajcache.db.models import Trajectory
from trajcache.jobs.pool import PlannerPool

_log = logging.getLogger(__name__)
SAMPLE_INTERVAL_S = 1.0
_PLANNER_STATUSES = ("failure", "error")
# Seconds: from a sub-millisecond lookup to a planner that uses a long budget.
_BUCKETS = (0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30)

if os.environ.get(MULTIPROC_ENV):  # each metric below opens its file there
    os.makedirs(os.environ[MULTIPROC_ENV], exist_ok=True)

PLAN_REQUESTS = Counter(
    "trajcache_plan_requests",
    "Plan requests answered (or refused: status refused), by where the trajectory came from "
    "(none: no trajectory), status and who asked (robot or seed_job).",
    ["source", "status", "requester"],
)
LOOKUP_SECONDS = Histogram(
    "trajcache_plan_lookup_seconds", "Time to find cached candidates.", buckets=_BUCKETS
)
VALIDATE_SECONDS = Histogram(
    "trajcache_plan_validate_seconds",
    "Time to validate cached candidates and planned paths.",
    buckets=_BUCKETS,
)
PLANNING_SECONDS = Histogram(
    "trajcache_plan_planning_seconds",
    "Time in the fallback planner, for requests that reached it.",
    buckets=_BUCKETS,
)
TOTAL_SECONDS = Histogram(
    "trajcache_plan_total_seconds",
    "Time to answer a plan request, by source and who asked (robot or seed_job).",
    ["source", "requester"],
    buckets=_BUCKETS,
)
POOL_QUEUE_DEPTH = Gauge(
    "trajcache_pool_queue_depth",
    "Planning runs submitted to the planner pool and not finished.",
    multiprocess_mode="livesum",
)
POOL_WORKER_CRASHES = Counter(
    "trajcache_pool_worker_crashes", "Planner worker processes that died during a request."
)
POOL_RECYCLES = Counter(
    "trajcache_pool_recycles", "Planner worker pools replaced after a crash or an overrun."
)
POOL_FAILED_RUNS = Counter(
    "trajcache_pool_failed_runs", "Planning runs that ended without a path (timeouts, errors)."
)
_POOL_COUNTERS = {
    "crashes": POOL_WORKER_CRASHES,
    "recycles": POOL_RECYCLES,
    "failures": POOL_FAILED_RUNS,
}


def record_refusal(*, requester: str) -> None:
    """Count one plan request refused before an answer (`refusals`)."""
    PLAN_REQUESTS.labels(source="none", status="refused", requester=requester).inc()


def record_plan(
    *, status: str, source: str | None, requester: str, timings: Mapping[str, float]
) -> None:
    """Count one answered plan request and observe the time (ms) of each of its steps."""
    source = source or "none"
    PLAN_REQUESTS.labels(source=source, status=status, requester=requester).inc()
    LOOKUP_SECONDS.observe(timings.get("lookup", 0.0) / 1e3)
    VALIDATE_SECONDS.observe(timings.get("validate", 0.0) / 1e3)
    if source in ("planner", "repaired") or status in _PLANNER_STATUSES:
        PLANNING_SECONDS.observe(timings.get("plan", 0.0) / 1e3)
    TOTAL_SECONDS.labels(source=source, requester=requester).observe(
        timings.get("total", 0.0) / 1e3
    )


class PoolSampler:
    """Copies the planner pool's queue depth and failure counters into the metrics."""

    def __init__(self, pool_fn: Callable[[], PlannerPool | None]) -> None:
        self._pool_fn = pool_fn  # the running pool, if any (sampling never starts one)
        self._lock = threading.Lock()
        self._pool: PlannerPool | None = None
        self._seen: dict[str, int] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def sample(self) -> None:
        """Read the pool's counters now (the pool is not started for this)."""
        pool = self._pool_fn()
        with self._lock:
            if pool is None:
                POOL_QUEUE_DEPTH.set(0)
                return
            if pool is not self._pool:  # a new pool counts from zero
                self._pool, self._seen = pool, {}
            stats = pool.stats()
            POOL_QUEUE_DEPTH.set(stats.queue_depth)
            for name, counter in _POOL_COUNTERS.items():
                value = int(getattr(stats, name))
                delta = value - self._seen.get(name, 0)
                if delta > 0:
                    counter.inc(delta)
                self._seen[name] = value

    def start(self, interval_s: float = SAMPLE_INTERVAL_S) -> None:
        """Sample every `interval_s` in a daemon thread until `stop`."""

        def run() -> None:
            while not self._stop.wait(interval_s):
                try:
                    self.sample()
                except Exception:  # a pool being replaced or closed; the next tick retries
                    _log.debug("planner pool sample failed", exc_info=True)

        self._thread = threading.Thread(target=run, name="trajcache-pool-metrics", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop sampling and take a last sample."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self.sample()


class CacheSizeCollector(Collector):
    """Cached trajectories per model, counted in the database at scrape time."""

    def __init__(self, sessions: sessionmaker[Session]) -> None:
        self._sessions = sessions

    def collect(self) -> Iterator[Metric]:
        """One sample per model; nothing (not an error) while the database is unreachable."""
        family = GaugeMetricFamily(
            "trajcache_cache_trajectories", "Trajectories in the cache, by model.", labels=["model"]
        )
        up = GaugeMetricFamily("trajcache_database_up", "Whether /metrics could read the database.")
        try:
            with self._sessions() as session:
                counts = session.execute(
                    sa.select(Trajectory.model_id, sa.func.count()).group_by(Trajectory.model_id)
                ).all()
        except SQLAlchemyError:
            up.add_metric([], 0)
            yield up
            return
        for model_id, count in counts:
            family.add_metric([model_id], int(count))
        up.add_metric([], 1)
        yield family
        yield up


def render(sessions: sessionmaker[Session]) -> bytes:
    """The exposition text: this process's metrics, or every process's in multiprocess mode,
    and the cache size read through `sessions`."""
    database = CollectorRegistry(auto_describe=True)
    database.register(CacheSizeCollector(sessions))
    if os.environ.get(MULTIPROC_ENV):
        merged = CollectorRegistry()
        multiprocess.MultiProcessCollector(merged)
        return generate_latest(merged) + generate_latest(database)
    return generate_latest(REGISTRY) + generate_latest(database)
