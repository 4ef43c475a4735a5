"""The reference setup shipped with trajcache: the robot, its restroom and its cleaning workload.

- `robot`: an xArm7-like mobile manipulator (URDF text and the loaded planar-base model).
- `restroom`: the restroom scene it cleans, with doors and seats at given angles.
- `tasks` and `cleaning`: the task configurations at each stall and a seeded generator of
  cleaning runs (the plan calls and the scene changes between them), the workload of the
  paper's protocol, of `trajcache demo` and of the benchmarks.
- `example_robots`: the robots of the `example-robot-data` package as it ships them (a second,
  real-robot workload for tests and benchmarks, and the files `trajcache robots fetch` writes;
  the package itself is the `robots` extra, and in `dev`).
"""

from __future__ import annotations

from trajcache.reference.cleaning import (
    PERTURBED_NOISE,
    CleaningRun,
    Noise,
    PlanCall,
    SceneEvent,
    cleaning_run,
    door_sweep_run,
)
from trajcache.reference.restroom import (
    RESTROOM_LAYOUT,
    STALL_FRONTS,
    STATIONS,
    BaseStation,
    RestroomLayout,
    StallFront,
    restroom_layout,
    restroom_scene,
)
from trajcache.reference.robot import (
    REFERENCE_BASE,
    REFERENCE_NAME,
    STOWED_ARM,
    reference_model,
    reference_urdf,
)
from trajcache.reference.tasks import TASKS, WorkStation, task_arm, task_state, work_stations

__all__ = [
    "PERTURBED_NOISE",
    "REFERENCE_BASE",
    "REFERENCE_NAME",
    "RESTROOM_LAYOUT",
    "STALL_FRONTS",
    "STATIONS",
    "STOWED_ARM",
    "TASKS",
    "BaseStation",
    "CleaningRun",
    "Noise",
    "PlanCall",
    "RestroomLayout",
    "SceneEvent",
    "StallFront",
    "WorkStation",
    "cleaning_run",
    "door_sweep_run",
    "reference_model",
    "reference_urdf",
    "restroom_layout",
    "restroom_scene",
    "task_arm",
    "task_state",
    "work_stations",
]
