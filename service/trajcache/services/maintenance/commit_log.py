"""Retention of the trajectory commit log: rows older than `commit_log_retention_s` go.

Replicas sync by reading the log (`services.catalog.index_store`), so a row is needed only until
every replica has read it; a replica that sleeps longer than the retention finds the oldest row
left above its high-water mark and reloads its indexes. Each replica prunes every
`PRUNE_EVERY_S` (the first time that long after its start); concurrent prunes are harmless (a
DELETE of rows already gone deletes nothing).
"""

from __future__ import annotations

import logging
from datetime import timedelta

from trajcache.db.commit_log import prune_commit_log
from trajcache.db.models import utcnow
from trajcache.services.maintenance.loop import BackgroundLoop

__all__ = ["PRUNE_EVERY_S", "CommitLogPruner"]

_log = logging.getLogger(__name__)
PRUNE_EVERY_S = 600.0


class CommitLogPruner(BackgroundLoop):
    """Deletes commit-log rows older than the retention, every `PRUNE_EVERY_S`."""

    thread_name = "commit-log-prune"
    step_name = "commit log prune"

    def first_pause_s(self) -> float:
        return PRUNE_EVERY_S

    def step(self) -> float:
        retention = timedelta(seconds=self.ctx.settings.commit_log_retention_s)
        with self.ctx.sessions() as session:
            pruned = prune_commit_log(session, before=utcnow() - retention)
        if pruned:
            _log.info("pruned %d commit log rows", pruned)
        return PRUNE_EVERY_S

    def failure_pause_s(self) -> float:
        return PRUNE_EVERY_S
