"""A Cartesian path request of a robot: the link's straight lines through waypoints, as joint
states certified in the robot's current scene, then timed.

The robot's model and scene are read as IK reads them (`services.ik.solve`); the path is
computed by `planning.cartesian`, its joint motions checked by the robot's certified validator
(the plan flow's, `validator_for`) whatever `avoid_collisions` says (false is listed in the
warnings as not honoured: a motion is never left unchecked), its distance from the lines
bounded (`geometry.model.cartesian_bound`: `max_deviation_m`), and the answer timed as a plan
answer is (`services.bookkeeping.answer_quality.answer_details`). A stopped path is an answer,
not an error: `fraction` and `status` say how far it went and why.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.model.cartesian_bound import deviation_bounds
from trajcache.geometry.model.kinematics import (
    StateInput,
    check_limits,
    check_states,
    resolve_state,
)
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, pose_matrix
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationStatus,
    validator_for,
)
from trajcache.planning.cartesian import (
    CartesianProblem,
    CartesianStatus,
    MotionVerdict,
    cartesian_path,
    sample_count,
)
from trajcache.services.bookkeeping.answer_quality import (
    AnswerDetails,
    QualityLevel,
    answer_details,
)
from trajcache.services.cartesian.store import CacheQuery, lookup_path, store_path
from trajcache.services.catalog.models import get_model, model_source
from trajcache.services.catalog.robots import robot_scene
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError
from trajcache.services.ik.solve import link_of
from trajcache.services.quality import TimingRequest

__all__ = ["CartesianAnswer", "CartesianRequest", "Waypoint", "answer_cartesian"]

Waypoint = tuple[tuple[float, float, float], tuple[float, float, float, float]]
MAX_SAMPLES = 2000  # the most samples one request may ask for
NOT_HONOURED = (
    "avoid_collisions=false is not honoured: every joint motion of a Cartesian path is "
    "certified collision-free in the robot's current scene"
)
_STATUS = {
    ValidationStatus.COLLISION: CartesianStatus.COLLISION,
    ValidationStatus.TOO_CLOSE: CartesianStatus.TOO_CLOSE,
    ValidationStatus.OUT_OF_LIMITS: CartesianStatus.OUT_OF_LIMITS,
}


@dataclass(frozen=True)
class CartesianRequest:
    """What a client asks: the link's waypoints from a start (the frame IK reads), the steps,
    the jump thresholds, and how near a cached path must be to serve."""

    start: StateInput
    waypoints: tuple[Waypoint, ...]
    link: str = ""
    max_step: float = 0.01
    max_rotation_step: float = 0.05
    jump_threshold: float = 0.0
    revolute_jump_threshold: float = 0.0
    prismatic_jump_threshold: float = 0.0
    position_tolerance: float = 1e-4
    orientation_tolerance: float = 1e-3
    avoid_collisions: bool = True
    timing: TimingRequest | None = field(default_factory=TimingRequest)
    cache: CacheQuery = field(default_factory=CacheQuery)
    names: dict[str, str] = field(default_factory=dict)  # field → the name the caller used


@dataclass
class CartesianAnswer:
    """The joint path reached, how far and why it stopped, where it came from."""

    status: CartesianStatus
    source: str  # "computed" or "cache"
    states: FloatArray
    fraction: float
    model: RobotModel  # as the robot holds its joints
    link: str
    max_deviation_m: float
    message: str
    warnings: list[str]
    details: AnswerDetails
    path_id: int | None
    timings_ms: dict[str, float]


def answer_cartesian(
    *, ctx: ServiceContext, robot_id: str, request: CartesianRequest
) -> CartesianAnswer:
    """The Cartesian path of `request` for robot `robot_id` in its current scene."""
    began = time.perf_counter()
    with ctx.sessions() as session:
        robot = robot_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        source = model_source(session=session, model_id=model.model_id, registry=ctx.models)
    checked = model_in_scene(model, robot.scene, robot.joint_values, cache=ctx.variants)
    kinematics = ctx.kinematics.get_or_build(
        checked, lambda: PinKinematics.build(checked, source.urdf)
    )
    link = link_of(checked, source.srdf, request.link, request.names)
    start = _start(checked, request)
    validator = validator_for(checked, robot.scene, ctx.settings, cache=ctx.validators)
    problem = _problem(kinematics, link, start, request, validator)
    _check_size(problem, request)
    read = time.perf_counter()
    cache = request.cache
    found = lookup_path(ctx, model.model_id, problem, cache) if cache.lookup else None
    path, path_id, origin = (found.path, found.path_id, "cache") if found else (None, None, "")
    looked = time.perf_counter()
    if path is None:
        path, origin = cartesian_path(problem), "computed"
        if path.fraction == 1.0 and cache.store:
            path_id = store_path(ctx, model.model_id, problem, path)
    solved = time.perf_counter()
    bounds = deviation_bounds(checked, link, path.states, path.lines, path.line_of)
    details = answer_details(
        settings=ctx.settings,
        validators=ctx.validators,
        model=checked,
        scene=robot.scene,
        states=path.states,
        timing=request.timing if len(path.states) > 1 else None,
        level=QualityLevel.BASIC,
    )
    done = time.perf_counter()
    warnings = [*path.notes] + ([] if request.avoid_collisions else [NOT_HONOURED])
    timings = {"db": read - began, "lookup": looked - read, "solve": solved - looked}
    timings.update({"timing": done - solved, "total": done - began})
    return CartesianAnswer(
        status=path.status,
        source=origin,
        states=path.states,
        fraction=path.fraction,
        model=checked,
        link=link,
        max_deviation_m=float(bounds.max()) if len(bounds) else 0.0,
        message=path.message,
        warnings=warnings,
        details=details,
        path_id=path_id,
        timings_ms={k: round(v * 1e3, 3) for k, v in timings.items()},
    )


def _problem(
    kinematics: PinKinematics,
    link: str,
    start: FloatArray,
    request: CartesianRequest,
    validator: TrajectoryValidator,
) -> CartesianProblem:
    return CartesianProblem(
        kinematics,
        link,
        start,
        _poses(request),
        max_step=request.max_step,
        max_rotation_step=request.max_rotation_step,
        jump_threshold=request.jump_threshold,
        revolute_jump_threshold=request.revolute_jump_threshold,
        prismatic_jump_threshold=request.prismatic_jump_threshold,
        position_tolerance=request.position_tolerance,
        orientation_tolerance=request.orientation_tolerance,
        validate_fn=lambda states: verdict_of(validator, states),
    )


def _check_size(problem: CartesianProblem, request: CartesianRequest) -> None:
    """InvalidInputError (422) for a path of more than MAX_SAMPLES samples."""
    kin = problem.kinematics
    origin = kin.link_pose(problem.start, kin.frame_id(problem.link))
    count = sample_count(origin, problem.waypoints, problem.max_step, problem.max_rotation_step)
    if count > MAX_SAMPLES:
        raise InvalidInputError(
            f"{request.names.get('waypoints', 'waypoints')}: the lines need {count} samples of "
            f"at most {problem.max_step:g} m and {problem.max_rotation_step:g} rad; at most "
            f"{MAX_SAMPLES} (a larger max_step, or nearer waypoints)"
        )


def verdict_of(validator: TrajectoryValidator, states: FloatArray) -> MotionVerdict:
    """The certified validator's word on the joint path through `states`: the states that
    lead a valid path, and why the next motion is not one (naming what it hits). The prefix
    kept is validated again until it is valid: a finding at a key state itself (its motion
    begins there) leaves that state out too."""
    result = validator.validate(states)
    if result.valid:
        return MotionVerdict(len(states))
    first, kept = result, len(states)
    while not result.valid and kept > 1:
        kept = min(kept - 1, max(1, result.segment + 1))
        result = validator.validate(states[:kept])
    where = f"on the motion from state {kept - 1} to {kept}"
    if not result.valid:  # the start itself
        where, first = "at the start", result
    text = first.message or first.status.value
    return MotionVerdict(kept, _STATUS[first.status], f"{text} ({where})")


def _start(model: RobotModel, request: CartesianRequest) -> FloatArray:
    name = request.names.get("start", "start")  # a StateError (422) names what does not fit
    start = check_states(model, resolve_state(model, request.start, name=name), name=name)[0]
    check_limits(model, start, name=name)
    return np.asarray(start, dtype=float)


def _poses(request: CartesianRequest) -> list[FloatArray]:
    """The waypoints as 4×4 poses; a SceneError (422) names a quaternion that is not a unit."""
    where = request.names.get("waypoints", "waypoints")
    poses = []
    for k, (position, orientation) in enumerate(request.waypoints):
        quaternion = unit_quaternion(list(orientation), f"{where}[{k}].orientation")
        poses.append(pose_matrix(list(position), quaternion))
    return poses
