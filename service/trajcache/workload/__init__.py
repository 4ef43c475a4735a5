"""The reference workload: task configurations and a seeded generator of cleaning runs."""

from __future__ import annotations

from trajcache.workload.cleaning import (
    PERTURBED_NOISE,
    CleaningRun,
    Noise,
    PlanCall,
    SceneEvent,
    cleaning_run,
    door_sweep_run,
)
from trajcache.workload.tasks import TASKS, WorkStation, task_arm, task_state, work_stations

__all__ = [
    "PERTURBED_NOISE",
    "TASKS",
    "CleaningRun",
    "Noise",
    "PlanCall",
    "SceneEvent",
    "WorkStation",
    "cleaning_run",
    "door_sweep_run",
    "task_arm",
    "task_state",
    "work_stations",
]
