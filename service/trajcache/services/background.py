"""Background work of one service process: the seed job scheduler (which also prunes old seed
jobs' scenes), timed eviction, the quality of imported trajectories and the pruning of the
trajectory commit log."""

from __future__ import annotations

from dataclasses import dataclass

from trajcache.services.context import ServiceContext
from trajcache.services.maintenance.backfill import QualityBackfill
from trajcache.services.maintenance.commit_log import CommitLogPruner
from trajcache.services.maintenance.eviction import EvictionTimer
from trajcache.services.seeding.scheduler import SeedScheduler


@dataclass
class Background:
    """The started background threads; `stop` ends them before the context closes."""

    seeds: SeedScheduler
    eviction: EvictionTimer | None
    quality: QualityBackfill | None = None
    commit_log: CommitLogPruner | None = None

    def stop(self) -> None:
        """Hand running seed jobs back and stop the timers."""
        if self.commit_log is not None:
            self.commit_log.stop()
        if self.quality is not None:
            self.quality.stop()
        if self.eviction is not None:
            self.eviction.stop()
        self.seeds.stop()


def start_background(ctx: ServiceContext) -> Background:
    """Start the seed scheduler (it resumes unfinished jobs at once), timed eviction, the
    background quality of imports (it resumes rows left pending, at once) and the commit log's
    pruning."""
    settings = ctx.settings
    eviction = None
    if settings.cache_max_per_model > 0 and settings.eviction_interval_s > 0:
        eviction = EvictionTimer(ctx).start()
    quality = QualityBackfill(ctx).start() if settings.quality_backfill_per_s > 0 else None
    return Background(
        seeds=SeedScheduler(ctx).start(),
        eviction=eviction,
        quality=quality,
        commit_log=CommitLogPruner(ctx).start(),
    )
