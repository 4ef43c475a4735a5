"""An IK request of a robot: its model as it holds its joints, its current scene, a seed, and
the solver of `geometry.model.ik`.

The robot's model and scene are read as a plan reads them (`services.catalog.robots
.robot_scene`, the model registry, `geometry.scene.variant.model_in_scene`), and a solution is
collision-free by the same checker that validates plans (`validator_for(...).checker`), free of
the scene and of self-collision. Starts, after the seed: the ends of the model's cached
trajectories whose link lies nearest the target, read from the end-pose index (at most
CACHED_STARTS, among every stored trajectory: `services.ik.cached`), then random restarts. No
solution is an answer with a status, not an error.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.collision.checker import FREE, CollisionChecker
from trajcache.geometry.model.ik import IkProblem, IkResult, IkStatus, PoseTarget, solve_ik
from trajcache.geometry.model.kinematics import (
    StateInput,
    check_limits,
    check_states,
    resolve_state,
)
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, pose_matrix
from trajcache.geometry.model.srdf import parse_srdf
from trajcache.geometry.path_quality import end_effector_link
from trajcache.geometry.scene.fields import unit_quaternion
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.geometry.validation.validator import validator_for
from trajcache.services.catalog.models import get_model, model_source
from trajcache.services.catalog.robots import robot_scene
from trajcache.services.context import ServiceContext
from trajcache.services.errors import InvalidInputError
from trajcache.services.ik.cached import nearest_starts, stored_count

IK_BUDGET_S = 0.05  # default time budget of one IK request
IK_BUDGET_MAX_S = 2.0  # the most a request may ask for

__all__ = ["IkAnswer", "IkRequest", "IkStatus", "answer_ik", "free_fn", "link_of"]


@dataclass(frozen=True)
class IkRequest:
    """What a client asks: a link at a pose (base frame; world for a planar base)."""

    link: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]  # x, y, z, w
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2
    seed: StateInput | None = None  # None: the robot's zero state, clipped into the limits
    avoid_collisions: bool = True
    move_base: bool = False
    budget_s: float | None = None
    solutions: int = 3
    names: dict[str, str] = field(default_factory=dict)  # field → the name the caller used


@dataclass
class IkAnswer:
    """The solver's answer for a robot, in its model's state order."""

    status: IkStatus
    state: FloatArray | None
    seed: FloatArray
    model: RobotModel  # as the robot holds its joints
    link: str  # the link posed
    message: str
    result: IkResult
    timings_ms: dict[str, float]


def answer_ik(*, ctx: ServiceContext, robot_id: str, request: IkRequest) -> IkAnswer:
    """Solve `request` for robot `robot_id` in its current scene."""
    began = time.perf_counter()
    with ctx.sessions() as session:
        robot = robot_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        source = model_source(session=session, model_id=model.model_id, registry=ctx.models)
        checked = model_in_scene(model, robot.scene, robot.joint_values, cache=ctx.variants)
        seed = _seed(checked, request)
        target = _target(link_of(checked, source.srdf, request.link, request.names), request)
        stored = stored_count(ctx.indexes, session, model)
        starts = nearest_starts(session, model, checked, target, seed, stored=stored)
    read = time.perf_counter()
    kinematics = ctx.kinematics.get_or_build(
        checked, lambda: PinKinematics.build(checked, source.urdf)
    )
    valid_fn = None
    if request.avoid_collisions:
        checker = validator_for(checked, robot.scene, ctx.settings, cache=ctx.validators).checker
        valid_fn = free_fn(checker)
    budget = request.budget_s if request.budget_s is not None else IK_BUDGET_S
    problem = IkProblem(
        kinematics,
        target,
        seed,
        move_base=request.move_base,
        starts=starts,
        valid_fn=valid_fn,
        solutions=request.solutions,
        budget_s=min(budget, IK_BUDGET_MAX_S),
    )
    result = solve_ik(problem)
    done = time.perf_counter()
    timings = {"db": read - began, "solve": done - read, "total": done - began}
    return IkAnswer(
        status=result.status,
        state=result.state,
        seed=seed,
        model=checked,
        link=target.link,
        message=_message(result, request),
        result=result,
        timings_ms={k: round(v * 1e3, 3) for k, v in timings.items()},
    )


def _seed(model: RobotModel, request: IkRequest) -> FloatArray:
    """The seed state: the request's, or zeros clipped into the limits."""
    if request.seed is None:
        return np.clip(np.zeros(model.dof), model.lower, model.upper)
    name = request.names.get("seed", "seed")  # a StateError (422) names what does not fit
    seed = check_states(model, resolve_state(model, request.seed, name=name), name=name)[0]
    check_limits(model, seed, name=name)
    return seed


def link_of(
    model: RobotModel, srdf: str | None, name: str, names: Mapping[str, str] | None = None
) -> str:
    """The link a request names: a link, an SRDF end effector (its parent link), or none (the
    model's end-effector link); InvalidInputError (422) when it names nothing known (`names`:
    the field names the caller used)."""
    if not name:
        return model.link_names[end_effector_link(model)]
    if name in model.link_names:
        return name
    effectors = parse_srdf(srdf).end_effectors if srdf else {}
    if effectors.get(name) in model.link_names:
        return effectors[name]
    known = ", ".join([*model.link_names, *(f"{e} (end effector)" for e in effectors)])
    raise InvalidInputError(
        f"{(names or {}).get('link', 'link')}: {name!r} is neither a link nor an SRDF "
        f"end effector of the model (known: {known})"
    )


def _target(link: str, request: IkRequest) -> PoseTarget:
    """The pose target; a SceneError (422) names a quaternion that is not a unit one."""
    where = request.names.get("orientation", "orientation")
    quaternion = unit_quaternion(list(request.orientation), where)  # a SceneError (422)
    pose = pose_matrix(list(request.position), quaternion)
    return PoseTarget(link, pose, request.position_tolerance, request.orientation_tolerance)


def free_fn(checker: CollisionChecker) -> Callable[[FloatArray], bool]:
    """A validity predicate: the state is free of the scene and of self-collision."""

    def free(state: FloatArray) -> bool:
        return bool(int(checker.check(state[None, :]).status[0]) == FREE)

    return free


def _message(result: IkResult, request: IkRequest) -> str:
    """Why there is no solution (empty on success)."""
    if result.status is IkStatus.NOT_FOUND:
        return (
            f"no state reaches the pose of {request.link!r} within {request.position_tolerance:g}"
            f" m and {request.orientation_tolerance:g} rad in the budget "
            f"({result.attempts} attempts)"
        )
    if result.status is IkStatus.IN_COLLISION:
        return (
            f"{result.rejected} states reach the pose of {request.link!r}, but every one is in "
            "collision"
        )
    return ""
