"""What goes into a planner and what comes out; picklable, so it crosses process boundaries."""

from __future__ import annotations

import pickle
import secrets
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import Resolution

SEED_LIMIT = 2**31 - 2  # seeds are 1 … SEED_LIMIT: valid for OMPL and a 32-bit SQL integer


def fresh_seed() -> int:
    """A random seed for one planning run, so that a retried request searches anew."""
    return secrets.randbelow(SEED_LIMIT) + 1


class PlannerStatus(str, Enum):
    """How a planning attempt ended (failure is a value, not an exception)."""

    SOLVED = "solved"
    TIMEOUT = "timeout"  # no path found within the budget
    UNCERTIFIED = "uncertified"  # paths found, none certified (nor repaired) within the budget
    INVALID_START = "invalid_start"
    INVALID_GOAL = "invalid_goal"
    ERROR = "error"  # the planner could not run (crashed worker, backend down, bad planner name)


@dataclass(frozen=True)
class ModelSource:
    """Everything needed to rebuild a RobotModel in a worker; workers cache by `model_id`.

    The mesh files travel in `files`, or wait in the pickle file `files_at` that a local pool
    wrote once for its workers (`jobs.local`): a worker reads them only to build a model it has
    not built yet, where pickling them into every task cost milliseconds (10 MB for the Panda of
    example-robot-data).
    """

    model_id: str
    urdf: str
    base: str
    joint_names: tuple[str, ...]
    files: dict[str, bytes] = field(default_factory=dict)
    srdf: str | None = None
    joint_values: dict[str, float] | str | None = None  # held joints, as registered
    files_at: str | None = None

    def mesh_files(self) -> dict[str, bytes]:
        """The mesh files, from `files_at` when they wait there."""
        if self.files_at is None:
            return self.files
        with open(self.files_at, "rb") as spooled:
            files: dict[str, bytes] = pickle.load(spooled)  # written by this service's pool
        return files


@dataclass(frozen=True)
class SceneSource:
    """A scene in its native payload form, or parsed; workers cache the parsed scene by `hash`.

    `stored`: the database holds the scene (a robot's scene version), so a Celery worker reads
    it by hash instead of receiving its payload.

    `parsed`: the scene itself, as the sender parsed and checked it (`SceneSource.of`). A local
    worker process receives it pickled and plans in it as it is: unpickling takes a tenth of
    parsing the payload again (0.07 against 0.7 ms, an MBM bookshelf). Only the JSON wire of
    Celery tasks needs the payload (`native`), built from it when asked. It is an attribute, not
    a field: the wire's schema (`jobs.wire`) never sees it, and pickling keeps it.
    """

    hash: str
    payload: dict[str, Any] | None = None
    stored: bool = False

    @classmethod
    def of(cls, scene: Scene, *, stored: bool = False) -> SceneSource:
        """The source of a scene parsed here."""
        source = cls(scene.hash, stored=stored)
        object.__setattr__(source, "_parsed", scene)
        return source

    @property
    def parsed(self) -> Scene | None:
        """The scene as its sender parsed it, if it was sent so."""
        scene: Scene | None = self.__dict__.get("_parsed")
        return scene

    def native(self) -> dict[str, Any]:
        """The native payload of the scene."""
        if self.payload is not None:
            return self.payload
        if self.parsed is None:
            raise ValueError(f"scene {self.hash!r} has neither a payload nor a parsed scene")
        return scene_to_payload(self.parsed)


@dataclass(frozen=True)
class PlanningProblem:
    """One planning query: robot, scene, endpoints, budget, planner choice and seed, and the
    validator settings its path is certified with (the service's, so that the worker's checks
    agree with the service's)."""

    model: ModelSource
    scene: SceneSource
    start: tuple[float, ...]
    goal: tuple[float, ...]
    budget_s: float = 2.0
    planner: str = "compiled"
    seed: int = 0  # the planners' random seed: the same seed repeats the same search
    shortcut_s: float = 0.25
    joint_values: tuple[tuple[str, float], ...] = ()  # the robot's held joint values, if set
    step_position_m: float = Resolution.position_m
    step_orientation_rad: float = Resolution.orientation_rad
    step_joint_rad: float = Resolution.joint_rad
    certified_validation: bool = True

    @property
    def resolution(self) -> Resolution:
        """The largest steps between checked samples, for motion checks and validation."""
        return Resolution(self.step_position_m, self.step_orientation_rad, self.step_joint_rad)


@dataclass
class PlanResult:
    """A planner's answer: a status, the path (key states) when solved, and statistics.

    `message` may reach the robot that asked; `detail` (an exception's text, a host name) only
    the plan event and the log.
    """

    status: PlannerStatus
    path: np.ndarray | None = None
    message: str = ""
    stats: dict[str, float] = field(default_factory=dict)
    seed: int | None = None  # the seed the planner ran with (None: no planner ran)
    detail: str = ""
    certificate: str = ""  # the worker's validator's, for `path` (geometry/validation/stamp.py)

    @property
    def solved(self) -> bool:
        """True when `path` holds a validated path."""
        return self.status is PlannerStatus.SOLVED and self.path is not None
