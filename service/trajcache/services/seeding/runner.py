"""One replica's run of one claimed seed job: bounded concurrency, progress, lease renewal.

Work items are submitted in order, at most `concurrency` in flight, each through the plan
flow (`plan_in_scene`, results stored as `sim`). Finished items are counted into the progress
only as part of a finished prefix (item `done` and all before it), so the progress written to
the database is exact and a resumed job can start at item `done`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

import numpy as np
import sqlalchemy as sa
from pydantic import ValidationError
from sqlalchemy.exc import SQLAlchemyError

from trajcache.db.models import SeedJob, utcnow
from trajcache.geometry.errors import GeometryError
from trajcache.services.catalog.models import get_model
from trajcache.services.context import ServiceContext
from trajcache.services.errors import ServiceError, UnavailableError
from trajcache.services.plan.flow import (
    PlanRequest,
    PlanSource,
    PlanStatus,
    plan_in_scene,
)
from trajcache.services.seeding.jobs import JobState, affected_rows, release_jobs
from trajcache.services.seeding.spec import SeedJobSpec
from trajcache.services.seeding.work import SeedWork, expand

_log = logging.getLogger(__name__)
MAX_ERRORS = 20  # most recent failed items kept on the job, with their reasons
RETRY_DELAYS_S = (0.5, 2.0, 5.0)  # an item the pool could not run (status error) is retried
POOL_READY_TIMEOUT_S = 120.0
_REASON_CHARS = 300


@dataclass(frozen=True)
class Outcome:
    """How one work item ended: `hit`, `planned`, `failed` (with the reason), or `skipped`
    (not run to the end because the job stopped; a resumed job runs it again). A planned path
    identical to a trajectory already stored is not `stored` again."""

    kind: str
    reason: str = ""
    stored: bool = False


@dataclass
class Progress:
    """Counters over the finished prefix of the work items; `stored` counts the planned paths
    newly stored (None: a job begun before that counter existed)."""

    done: int
    hits: int
    planned: int
    failed: int
    errors: list[dict[str, Any]] = field(default_factory=list)
    stored: int | None = 0

    def absorb(self, finished: dict[int, Outcome], labels: Callable[[int], str]) -> None:
        """Count the finished items that extend the prefix."""
        while self.done in finished:
            outcome = finished.pop(self.done)
            if outcome.kind == "hit":
                self.hits += 1
            elif outcome.kind == "planned":
                self.planned += 1
                if outcome.stored and self.stored is not None:
                    self.stored += 1
            else:
                self.failed += 1
                entry = {"index": self.done, "label": labels(self.done), "reason": outcome.reason}
                self.errors = [*self.errors, entry][-MAX_ERRORS:]
            self.done += 1

    def values(self) -> dict[str, Any]:
        """The columns of the job row these counters fill."""
        return {
            "done": self.done,
            "hits": self.hits,
            "planned": self.planned,
            "stored": self.stored,
            "failed": self.failed,
            "errors": list(self.errors),
        }


def plan_request(spec: SeedJobSpec, ctx: ServiceContext, start: Any, goal: Any) -> PlanRequest:
    """The plan request of one work item, its options resolved against the settings."""
    s, o = ctx.settings, spec.options
    return PlanRequest(
        start=np.asarray(start, dtype=float),
        goal=np.asarray(goal, dtype=float),
        threshold=o.threshold or s.lookup_threshold,
        max_candidates=o.max_candidates or s.max_candidates,
        fallback=True,
        budget_s=o.budget_s or s.plan_budget_s,
        planner=o.planner or s.default_planner,
        arm_only=o.match == "arm",
    )


class JobRun:
    """Runs one job in a thread of its own while this replica holds the job's lease."""

    def __init__(
        self, ctx: ServiceContext, job_id: int, owner: str, *, on_exit: Callable[[int], None]
    ) -> None:
        self.ctx = ctx
        self.job_id = job_id
        self.owner = owner
        self.caller = f"seed-job-{job_id}"  # robot_id of its plan events (requester seed_job)
        self._on_exit = on_exit
        self._wake = threading.Event()
        self._halt = threading.Event()  # set with `_stop`: ends waits between retries
        self._stop: str | None = None  # "cancelled" | "shutdown"
        self._thread = threading.Thread(target=self._main, name=self.caller, daemon=True)

    def start(self) -> None:
        """Run the job in the background."""
        self._thread.start()

    def join(self, timeout_s: float | None = None) -> None:
        """Wait for the run to end."""
        self._thread.join(timeout_s)

    def cancel(self) -> None:
        """Stop submitting work now (the job row is already `cancelled`)."""
        self._stop = "cancelled"
        self._halt.set()
        self._wake.set()

    def shut_down(self) -> None:
        """Stop, write the progress and hand the job back (`queued`) for a later resume."""
        if self._stop is None:
            self._stop = "shutdown"
        self._halt.set()
        self._wake.set()

    def _main(self) -> None:
        try:
            self._run()
        except Exception:
            _log.exception("seed job %s stopped by an unexpected error", self.job_id)
        finally:
            self._on_exit(self.job_id)

    def _load(self) -> tuple[SeedJobSpec, Progress, int] | None:
        with self.ctx.sessions() as session:
            row = session.get(SeedJob, self.job_id)
            if row is None or row.lease_owner != self.owner:
                return None
            progress = Progress(
                row.done, row.hits, row.planned, row.failed, list(row.errors), row.stored
            )
            spec_json, total = row.spec, row.total
        try:
            spec = SeedJobSpec.model_validate(spec_json)
        except ValidationError as exc:
            self._end(JobState.FAILED, progress, f"the stored job is not valid: {exc}")
            return None
        return spec, progress, total

    def _run(self) -> None:
        loaded = self._load()
        if loaded is None:
            return
        spec, progress, total = loaded
        try:
            with self.ctx.sessions() as session:
                model = get_model(session=session, registry=self.ctx.models, model_id=spec.model_id)
            work = expand(spec, model=model, settings=self.ctx.settings)
        except (ServiceError, GeometryError) as exc:
            self._end(JobState.FAILED, progress, f"the job cannot run: {exc}")
            return
        if len(work.items) != total:
            message = f"the job now expands to {len(work.items)} requests, not {total}"
            self._end(JobState.FAILED, progress, message)
            return
        self._warm_pool()
        stopped = self._loop(spec, work, progress)
        if stopped is None:
            self._end(JobState.COMPLETED, progress)
        elif stopped == "shutdown":
            self._hand_back(progress)

    def _loop(self, spec: SeedJobSpec, work: SeedWork, progress: Progress) -> str | None:
        """Plan every item from `progress.done` on; why it stopped early, or None when done."""
        settings = self.ctx.settings
        concurrency = spec.concurrency or settings.seed_concurrency
        total = len(work.items)
        finished: dict[int, Outcome] = {}
        in_flight: dict[Future[Outcome], int] = {}
        next_index = progress.done
        began, done_at_claim = time.monotonic(), progress.done
        last_beat = time.monotonic()
        stopped: str | None = None
        pool = ThreadPoolExecutor(concurrency, thread_name_prefix=self.caller)
        try:
            while True:
                stopped = self._stop
                if stopped is not None:
                    break
                while len(in_flight) < concurrency and next_index < total:
                    future = pool.submit(self._plan_one, spec, work, next_index)
                    future.add_done_callback(lambda _f: self._wake.set())
                    in_flight[future] = next_index
                    next_index += 1
                if not in_flight:
                    break
                until_beat = settings.seed_heartbeat_s - (time.monotonic() - last_beat)
                self._wake.wait(max(0.0, until_beat))
                self._wake.clear()
                for future in [f for f in in_flight if f.done()]:
                    _collect(finished, in_flight.pop(future), future)
                progress.absorb(finished, lambda i: work.items[i].label)
                if time.monotonic() - last_beat >= settings.seed_heartbeat_s:
                    eta = _eta(progress.done - done_at_claim, total - progress.done, began)
                    stopped = self._beat(progress, eta)
                    last_beat = time.monotonic()
                    if stopped is not None:
                        break
        finally:
            # A cancelled or lost job leaves its in-flight requests behind; a shutdown waits
            # for them (they end within their budget) so the progress written is final.
            pool.shutdown(wait=stopped in (None, "shutdown"), cancel_futures=True)
        if stopped == "shutdown":
            for future, index in in_flight.items():
                _collect(finished, index, future)
            progress.absorb(finished, lambda i: work.items[i].label)
        return stopped

    def _warm_pool(self) -> None:
        """Wait until the local planner workers are up, so cold starts do not fail items."""
        pool = self.ctx.planner_pool()
        wait_ready = getattr(getattr(pool, "backend", None), "wait_ready", None)
        deadline = time.monotonic() + POOL_READY_TIMEOUT_S
        while callable(wait_ready) and time.monotonic() < deadline:
            if wait_ready(1.0) or self._halt.wait(0.2):
                return

    def _plan_one(self, spec: SeedJobSpec, work: SeedWork, index: int) -> Outcome:
        """Plan one item; a request the pool could not run is retried after a pause."""
        outcome = self._attempt(spec, work, index)
        for delay in RETRY_DELAYS_S:
            if outcome.kind != "error":
                break
            if self._halt.wait(delay):
                return Outcome("skipped")
            outcome = self._attempt(spec, work, index)
        return Outcome("failed", outcome.reason) if outcome.kind == "error" else outcome

    def _attempt(self, spec: SeedJobSpec, work: SeedWork, index: int) -> Outcome:
        if self._stop is not None:
            return Outcome("skipped")
        item = work.items[index]
        try:
            answer = plan_in_scene(
                ctx=self.ctx,
                caller=self.caller,
                model_id=spec.model_id,
                scene=work.scenes[item.scene],
                request=plan_request(spec, self.ctx, item.start, item.goal),
                store_as="sim",
            )
        except UnavailableError as exc:  # the pool or the database: worth a retry
            return Outcome("error", str(exc)[:_REASON_CHARS])
        except (GeometryError, ServiceError) as exc:
            return Outcome("failed", str(exc)[:_REASON_CHARS])
        except Exception as exc:
            _log.exception("seed job %s: item %s failed", self.job_id, index)
            return Outcome("failed", f"{type(exc).__name__}: {exc}"[:_REASON_CHARS])
        if answer.status is PlanStatus.SUCCESS:
            if answer.source is PlanSource.CACHE:
                return Outcome("hit")
            return Outcome("planned", stored=answer.stored is not False)
        reason = f"{answer.status.value}: {answer.message}".rstrip(": ")[:_REASON_CHARS]
        return Outcome("error" if answer.status is PlanStatus.ERROR else "failed", reason)

    def _leased(self) -> sa.ColumnElement[bool]:
        return sa.and_(
            SeedJob.id == self.job_id,
            SeedJob.lease_owner == self.owner,
            SeedJob.state == JobState.RUNNING.value,
        )

    def _beat(self, progress: Progress, eta_at: datetime | None) -> str | None:
        """Write progress and renew the lease; why to stop when the job is no longer ours."""
        now = utcnow()
        try:
            with self.ctx.sessions() as session:
                result = session.execute(
                    sa.update(SeedJob)
                    .where(self._leased())
                    .values(
                        **progress.values(),
                        lease_expires_at=now + timedelta(seconds=self.ctx.settings.seed_lease_s),
                        eta_at=eta_at,
                        updated_at=now,
                    )
                    .execution_options(synchronize_session=False)
                )
                session.commit()
                if affected_rows(result) == 1:
                    return None
                state = session.scalar(sa.select(SeedJob.state).where(SeedJob.id == self.job_id))
        except SQLAlchemyError as exc:  # keep planning; the next heartbeat tries again
            _log.warning("seed job %s: progress not written: %s", self.job_id, exc)
            return None
        return "cancelled" if state == JobState.CANCELLED.value else "lost"

    def _end(self, state: JobState, progress: Progress, message: str | None = None) -> None:
        values = {**progress.values(), "message": message and message[:500]}
        with self.ctx.sessions() as session:
            release_jobs(session=session, where=self._leased(), state=state, values=values)

    def _hand_back(self, progress: Progress) -> None:
        with self.ctx.sessions() as session:
            release_jobs(
                session=session,
                where=self._leased(),
                state=JobState.QUEUED,
                values=progress.values(),
            )


def _collect(finished: dict[int, Outcome], index: int, future: Future[Outcome]) -> None:
    """Keep a finished item's outcome; a skipped or cancelled item stays to be run."""
    if future.done() and not future.cancelled():
        outcome = future.result()
        if outcome.kind != "skipped":
            finished[index] = outcome


def _eta(done_here: int, remaining: int, began: float) -> datetime | None:
    """When the job should end, at the rate of this run so far."""
    if done_here <= 0:
        return None
    rate = done_here / max(time.monotonic() - began, 1e-6)
    return utcnow() + timedelta(seconds=remaining / rate)
