"""Retention of seed jobs' stored scenes (`SeedJobScene`): old ones go unless a path uses them.

A seed job keeps its scenes so the trajectories it seeded can be shown in the scene they were
planned in (`services/view/scenes.py`). Once a job finished more than
`seed_scene_retention_days` ago, its scenes are deleted, except those whose hash a stored
trajectory still names (`trajectories.scene_hash`): such a scene stays as long as one of its
trajectories does, and goes at a later prune once they are evicted or deleted. Scenes of queued
or running jobs are never pruned. Each replica's seed scheduler prunes at start and then every
`PRUNE_EVERY_S`; concurrent prunes are harmless (a DELETE of rows already gone deletes nothing).
"""

from __future__ import annotations

from datetime import datetime, timedelta

import sqlalchemy as sa
from sqlalchemy.orm import Session

from trajcache.db.models import SeedJob, SeedJobScene, Trajectory, utcnow

PRUNE_EVERY_S = 3600.0


def prune_seed_scenes(
    session: Session, *, retention: timedelta, now: datetime | None = None
) -> int:
    """Delete the scenes of jobs finished before `now - retention` that no trajectory names;
    commit, and return how many were deleted."""
    cutoff = (now or utcnow()) - retention
    finished = sa.select(SeedJob.id).where(
        SeedJob.finished_at.is_not(None), SeedJob.finished_at < cutoff
    )
    # NOT IN one list of the hashes in use: one pass over the trajectories, not one per scene.
    used = sa.select(Trajectory.scene_hash).where(Trajectory.scene_hash.is_not(None))
    deleted = session.execute(
        sa.delete(SeedJobScene).where(
            SeedJobScene.job_id.in_(finished), SeedJobScene.hash.not_in(used)
        )
    )
    session.commit()
    return int(deleted.rowcount or 0)  # type: ignore[attr-defined]
