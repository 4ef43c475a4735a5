"""One plan request as it is answered: what it asks, where it runs, and what it found so far.

A :class:`PlanAttempt` is built once per request (as OMPL's `ProblemDefinition` is per problem)
and handed to each step of the flow (`services.plan.flow`): the context, the caller and its
origin, the model and scene, the request with its start and goal resolved, the validator (built
once, on first use), the clock that times each phase, and the candidates that failed validation
(one list, `services.bookkeeping.rejections.Rejections`, that the answer and its bookkeeping
read).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from sqlalchemy import Connection
from sqlalchemy.orm import Session

from trajcache.cache.index import Match
from trajcache.cache.memo import MemoScope, MemoUse
from trajcache.geometry.model.kinematics import StateInput
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.certificates import CertificateUse
from trajcache.geometry.validation.validator import TrajectoryValidator, validator_for
from trajcache.services.bookkeeping.answer_quality import AnswerDetails
from trajcache.services.bookkeeping.outcomes import Requester
from trajcache.services.bookkeeping.record_batch import WriterJob
from trajcache.services.bookkeeping.rejections import Rejections
from trajcache.services.catalog.certificates import CertificateWrite
from trajcache.services.context import ServiceContext

__all__ = [
    "GoalKind",
    "GoalPose",
    "Origin",
    "PhaseClock",
    "PlanAnswer",
    "PlanAttempt",
    "PlanRequest",
    "PlanSource",
    "PlanStatus",
]

PHASES = ("lookup", "validate", "plan", "db")


class PlanStatus(str, Enum):
    """How a plan request ended."""

    SUCCESS = "success"
    MISS = "miss"  # no valid cached candidate and no fallback planning asked for or available
    FAILURE = "failure"  # the planner found no path within its budget
    ERROR = "error"  # the planner could not run (pool broken, backend down): answered with 503


class GoalKind(str, Enum):
    """What a plan request's goal was: a state, or a link's pose (`goal_pose`)."""

    JOINT = "joint"
    POSE = "pose"


class PlanSource(str, Enum):
    """Where an answered trajectory came from."""

    CACHE = "cache"
    PLANNER = "planner"
    REPAIRED = "repaired"  # a cached path whose failing stretch the planner replaced


@dataclass(frozen=True)
class GoalPose:
    """A link at a pose (the model's base frame; the world for a planar base), within
    tolerances (metres; radians of the rotation between the two orientations)."""

    link: str  # a link, an SRDF end effector, or "" (the model's end-effector link)
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]  # x, y, z, w
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2


@dataclass(frozen=True)
class PlanRequest:
    """A validated plan request with its options resolved against the settings."""

    start: StateInput  # values in state_names order, a {joint: value} map, or a named state
    goal: StateInput | None  # None: `goal_pose` names the goal
    threshold: float
    max_candidates: int
    fallback: bool = True
    budget_s: float = 2.0
    planner: str = "compiled"
    arm_only: bool = False  # match on arm joints only when the base does not move
    lookup: bool = True  # False: skip the cache and plan (a fresh plan is still stored)
    goal_pose: GoalPose | None = None  # the goal as a link's pose (`services.plan.pose_goal`)


@dataclass(frozen=True)
class Origin:
    """Where a request comes from: who asked, what a planned trajectory is stored as, and if
    it is real."""

    store_source: str  # source of a trajectory the planner finds for this request
    store_robot_id: str | None
    real: bool  # a real robot: a hit counts as a validation of the trajectory in the real world
    held: Mapping[str, float] | None = None  # the robot's own held joint values, if it set any
    requester: Requester = Requester.ROBOT  # recorded in the plan event and the metrics
    scene_stored: bool = False  # the scene is a stored scene version (a robot's uploaded one)


@dataclass
class PlanAnswer:
    """What the plan endpoint returns."""

    status: PlanStatus
    source: PlanSource | None
    trajectory_id: int | None
    states: np.ndarray | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str = ""
    rejected: list[dict[str, object]] = field(default_factory=list)
    record: int | None = None  # sequence number of the bookkeeping in `ctx.records`, if queued
    memo: MemoUse | None = None  # how the served cached trajectory was validated
    details: AnswerDetails | None = None  # quality and timing, when the caller asked for extras
    planner: str | None = None  # the planner that found a planned answer's path
    certificate: CertificateUse | None = None  # how the served candidate's certificate served
    ends_proved: float | None = None  # the share of its new end segments their clearance proved
    warnings: list[str] = field(default_factory=list)  # what the caller should know (no scene)
    stored: bool | None = None  # a planned path: newly stored (False: identical to a stored one)
    goal_state: np.ndarray | None = None  # a pose goal's state
    goal_found_by: str | None = None  # how it was found: "cached" or "ik"


class PhaseClock:
    """Time spent per phase of a request; `measure` adds a block's time to its phase."""

    __slots__ = ("arrived", "began", "spent")

    def __init__(self) -> None:
        self.began = time.perf_counter()
        self.arrived = time.monotonic()  # what replica syncs must cover
        self.spent = dict.fromkeys(PHASES, 0.0)

    @contextmanager
    def measure(self, phase: str) -> Iterator[None]:
        """Add the time the block takes to `phase` (one of lookup, validate, plan, db)."""
        began = time.perf_counter()
        try:
            yield
        finally:
            self.spent[phase] += time.perf_counter() - began

    def seconds(self, phase: str) -> float:
        """Time spent in `phase` so far (s)."""
        return self.spent[phase]

    def timings(self) -> dict[str, float]:
        """Milliseconds per phase and in all, rounded to the microsecond."""
        total = (time.perf_counter() - self.began) * 1e3
        timings = {phase: round(s * 1e3, 3) for phase, s in self.spent.items()}
        timings["total"] = round(total, 3)
        return timings


@dataclass(eq=False)
class PlanAttempt:
    """One plan request being answered, in one session; its reads before validation (the
    robot, its scene, the replica sync, the candidates) run on a Core connection of their own,
    closed when the lookup ends."""

    ctx: ServiceContext
    session: Session
    reads: Connection
    caller: str  # the robot (or seed job) recorded in the plan event
    origin: Origin
    model: RobotModel  # as registered: what the cache and the planner key on
    scene: Scene
    request: PlanRequest
    clock: PhaseClock
    checked: RobotModel  # `model` as the robot holds its joints in `scene`: what is validated
    start: np.ndarray
    goal: np.ndarray
    rejections: Rejections = field(default_factory=Rejections)  # failed validation, in order
    candidates: dict[int, np.ndarray] = field(default_factory=dict)  # key states, by id
    tried: int = 0  # candidates counted in the answer and its plan event
    certificates: list[CertificateWrite] = field(default_factory=list)  # to write with the record
    certificate_use: CertificateUse | None = None  # the last certificate a validation used
    writer_jobs: list[WriterJob] = field(default_factory=list)  # for the record writer
    ends_missing: list[np.ndarray] = field(default_factory=list)  # stored end segments without
    # a clearance here, of the candidate being validated
    ends_proved: list[float] = field(default_factory=list)  # end segments' shares proved by
    # their stored clearance (`end_clearance.py`), for each end validated, in order
    goal_found_by: str | None = None  # a pose goal's state came from: "cached" or "ik"
    goal_path: Match | None = None  # the cached path whose end it was found from, if one
    pose_goal_ms: float = 0.0  # finding a pose goal's state (part of the lookup phase)

    @functools.cached_property
    def validator(self) -> TrajectoryValidator:
        """The validator of the checked model in the scene, under the service's settings."""
        return validator_for(self.checked, self.scene, self.ctx.settings, cache=self.ctx.validators)

    @functools.cached_property
    def memo_scope(self) -> MemoScope | None:
        """What the validator's verdicts depend on besides the states (`cache.memo`)."""
        return MemoScope.of(self.validator)

    @property
    def goal_kind(self) -> GoalKind:
        """What the request's goal was: a state, or a link's pose."""
        return GoalKind.JOINT if self.request.goal_pose is None else GoalKind.POSE

    def event(
        self,
        status: PlanStatus,
        *,
        source: PlanSource | None = None,
        trajectory_id: int | None = None,
        timings: Mapping[str, float],
        error: str | None = None,
        seed: int | None = None,  # the planner's seed, when the request planned
    ) -> dict[str, object]:
        """The plan_events column values of this request's outcome."""
        return {
            "robot_id": self.caller,
            "requester": self.origin.requester.value,
            "model_id": self.model.model_id,
            "scene_hash": self.scene.hash,
            "status": status.value,
            "source": source.value if source else None,
            "trajectory_id": trajectory_id,
            "candidates_tried": self.tried,
            "lookup_ms": timings["lookup"],
            "validate_ms": timings["validate"],
            "plan_ms": timings["plan"],
            "total_ms": timings["total"],
            "error": (error or None) and error[:500],
            "seed": seed,
            "rejections": None,  # the record writer fills it in (`bookkeeping.rejections`)
            "goal_kind": self.goal_kind.value,
            "goal_pose": _pose_record(self.request.goal_pose),
        }


def _pose_record(goal: GoalPose | None) -> dict[str, object] | None:
    """A goal pose as its plan event keeps it (None: the goal was a state)."""
    if goal is None:
        return None
    return {
        "link": goal.link,
        "position": [float(v) for v in goal.position],
        "orientation": [float(v) for v in goal.orientation],
        "position_tolerance": float(goal.position_tolerance),
        "orientation_tolerance": float(goal.orientation_tolerance),
    }
