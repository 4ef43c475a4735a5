"""Retention of the trajectory commit log and of the tombstones of deleted trajectories: rows
older than `commit_log_retention_s` go.

Replicas sync by reading both (`services.catalog.index_store`), so a row is needed only until
every replica has read it; a replica that sleeps longer than the retention finds the oldest row
left of either above its high-water mark and reloads its indexes. Without it, tombstones (one per
deleted or evicted trajectory) would grow without bound. Each replica prunes every
`PRUNE_EVERY_S` (the first time that long after its start); concurrent prunes are harmless (a
DELETE of rows already gone deletes nothing).
"""

from __future__ import annotations

import logging
from datetime import timedelta

from trajcache.db.commit_log import prune_commit_log, prune_tombstones
from trajcache.db.models import utcnow
from trajcache.services.maintenance.loop import BackgroundLoop

__all__ = ["PRUNE_EVERY_S", "CommitLogPruner"]

_log = logging.getLogger(__name__)
PRUNE_EVERY_S = 600.0


class CommitLogPruner(BackgroundLoop):
    """Deletes commit-log rows and tombstones older than the retention, every `PRUNE_EVERY_S`."""

    thread_name = "commit-log-prune"
    step_name = "commit log prune"

    def first_pause_s(self) -> float:
        return PRUNE_EVERY_S

    def step(self) -> float:
        retention = timedelta(seconds=self.ctx.settings.commit_log_retention_s)
        before = utcnow() - retention
        with self.ctx.sessions() as session:
            pruned = prune_commit_log(session, before=before)
            tombstones = prune_tombstones(session, before=before)
        if pruned or tombstones:
            _log.info("pruned %d commit log rows and %d tombstones", pruned, tombstones)
        return PRUNE_EVERY_S

    def failure_pause_s(self) -> float:
        return PRUNE_EVERY_S
