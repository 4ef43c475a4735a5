"""Bulk import: batches inside one transaction, the previous format, background quality."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from tests.services.maintenance.test_transfer import LONG_AGO, new_ctx, rows, run_import
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.db.models import RobotModel, Trajectory
from trajcache.services.background import start_background
from trajcache.services.context import ServiceContext
from trajcache.services.maintenance import backfill
from trajcache.services.maintenance.bulk_insert import BatchWriter
from trajcache.services.maintenance.importer import ImportFormatError

V1_EXPORT = Path(__file__).parents[2] / "data" / "exports" / "v1.jsonl"


@pytest.fixture
def target_ctx(database_url: str) -> Iterator[ServiceContext]:
    ctx = new_ctx(database_url)
    yield ctx
    ctx.close()


def v1_lines() -> list[str]:
    """An export written by the previous release (format version 1: no end line)."""
    return V1_EXPORT.read_text(encoding="utf-8").splitlines()


def many(count: int) -> list[str]:
    """The v1 export's arm model and `count` trajectories of it, as a version-2 export."""
    header, model, trajectory = (json.loads(line) for line in v1_lines()[:3])
    lines = [json.dumps({**header, "version": 2}), json.dumps(model)]
    for k in range(count):
        states = [[0.0, 0.0], [0.001 * (k + 1), 0.5]]
        lines.append(json.dumps({**trajectory, "states": states, "content_hash": None}))
    lines.append(json.dumps({"type": "end", "trajectories": count}))
    return lines


def count(ctx: ServiceContext, table: type[Any]) -> int:
    with ctx.sessions() as session:
        return int(session.scalar(sa.select(sa.func.count()).select_from(table)) or 0)


def test_an_export_of_the_previous_release_imports(target_ctx: ServiceContext) -> None:
    lines = v1_lines()
    assert json.loads(lines[0])["version"] == 1
    assert all(json.loads(line)["type"] != "end" for line in lines)
    report = run_import(target_ctx, lines)
    assert (report.inserted, report.models_created, report.rejected_count) == (4, 2, 0)
    stored = rows(target_ctx)
    assert sorted(r.source for r in stored) == ["planner", "real", "sim", "sim"]
    used = next(r for r in stored if r.hits == 7)
    assert (used.failures, used.real_validations, used.created_at) == (2, 3, LONG_AGO)
    assert all(r.quality_pending and r.duration_s is None for r in stored)


def test_rows_are_written_in_batches_and_duplicates_counted(target_ctx: ServiceContext) -> None:
    lines = many(7)
    doubled = [*lines[:-1], lines[3], lines[-1]]  # a repeat, in a later batch
    report = run_import(target_ctx, doubled, batch_rows=3)
    assert (report.inserted, report.duplicates) == (7, 1)
    again = run_import(target_ctx, lines, batch_rows=3)
    assert (again.inserted, again.duplicates) == (0, 7)
    assert count(target_ctx, Trajectory) == 7


def test_a_failing_batch_leaves_nothing_half_imported(
    target_ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    flushes = []
    original = BatchWriter.flush

    def failing_flush(self: BatchWriter) -> None:
        flushes.append(len(self._pending))
        if len(flushes) == 3:  # two batches are written (not committed) by now
            raise RuntimeError("the disk is full")
        original(self)

    monkeypatch.setattr(BatchWriter, "flush", failing_flush)
    with pytest.raises(RuntimeError, match="disk is full"):
        run_import(target_ctx, many(10), batch_rows=3)
    assert flushes == [3, 3, 3]
    assert count(target_ctx, Trajectory) == 0
    assert count(target_ctx, RobotModel) == 0


def test_a_cut_after_several_batches_imports_nothing(target_ctx: ServiceContext) -> None:
    lines = many(10)
    with pytest.raises(ImportFormatError, match="line 13: not JSON"):
        run_import(target_ctx, [*lines[:-1], lines[-2][:30]], batch_rows=3)
    with pytest.raises(ImportFormatError, match="cut short"):
        run_import(target_ctx, lines[:-1], batch_rows=3)  # ends at a line's end, no end line
    assert count(target_ctx, Trajectory) == 0
    assert run_import(target_ctx, lines, batch_rows=3).inserted == 10


def test_background_quality_fills_pending_rows(target_ctx: ServiceContext) -> None:
    run_import(target_ctx, many(5))
    with target_ctx.sessions() as session:
        assert backfill.pending_count(session) == 5
    assert backfill.backfill_batch(target_ctx, 2) == 2
    with target_ctx.sessions() as session:
        assert backfill.pending_count(session) == 3
        done = session.scalars(sa.select(Trajectory).where(Trajectory.quality_pending.is_(False)))
        assert all(r.duration_s is not None and r.length is not None for r in done)


def test_background_quality_resumes_after_a_restart(database_url: str) -> None:
    first = new_ctx(database_url)
    try:
        run_import(first, many(6))  # the process stops before computing anything
    finally:
        first.close()
    settings = Settings(database_url=database_url, worker_backend="none")
    restarted = ServiceContext.create(settings.model_copy(update={"quality_backfill_per_s": 50}))
    background = start_background(restarted)
    try:
        assert background.quality is not None

        def pending() -> int:
            with restarted.sessions() as session:
                return backfill.pending_count(session)

        assert wait_until(lambda: pending() == 0, timeout_s=60, interval_s=0.1)
    finally:
        background.stop()
        restarted.close()
    off = ServiceContext.create(settings.model_copy(update={"quality_backfill_per_s": 0}))
    try:
        quiet = start_background(off)
        assert quiet.quality is None
        quiet.stop()
    finally:
        off.close()


@pytest.mark.parametrize(
    ("rate", "done", "elapsed", "batch", "pause"),
    [
        (50.0, 50, 0.3, 50, 0.7),  # a second's worth took 0.3 s: rest the other 0.7
        (50.0, 50, 1.4, 50, 0.0),  # slower than the rate: no rest, never faster
        (2.5, 3, 0.1, 3, 1.1),
        (1000.0, 200, 0.1, backfill.MAX_BATCH, 0.1),
        (50.0, 0, 0.01, 50, backfill.IDLE_POLL_S),  # nothing pending: look again later
    ],
)
def test_background_quality_is_throttled(
    rate: float, done: int, elapsed: float, batch: int, pause: float
) -> None:
    assert backfill.batch_size(rate) == batch
    assert backfill.pause_after(done, rate, elapsed) == pytest.approx(pause)
