"""A Cartesian path: a link's origin along straight lines through waypoints, as joint states.

From the link's pose at the start state, straight lines (position linear, orientation slerp)
through each waypoint in turn, sampled so that no step exceeds `max_step` (m) nor
`max_rotation_step` (rad). Each sample is solved by damped least squares from the previous
sample's state (a warm start, `ik.descend_from_seed`: no restarts, so a solution stays on its
branch; a joint at a limit that a step would push out is held there, so the others take up the
motion). The path stops at the first sample that

1. has no IK solution within the tolerances (the joint limits hold by projection), or
2. jumps: a revolute (or continuous) joint changes by more than `revolute_jump_threshold`, a
   prismatic one by more than `prismatic_jump_threshold` (absolute; 0 disables), or, as
   MoveIt's relative `jump_threshold` reads (0 disables; checked once every sample is solved,
   on paths of at least MIN_STEPS_FOR_JUMP steps), a step longer than `jump_threshold` times
   the mean step in joint space; or
3. begins a joint motion that `validate_fn` rejects (the service passes its certified
   validator: collision, too close to certify, out of limits), checked last and in order.

`fraction` is MoveIt's: with N waypoints, each line counts 1/N, and a line stopped short counts
the share of its samples reached. The answer says why it stopped. Nothing here knows the scene.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation, Slerp

from trajcache.geometry.model.ik import IkProblem, PoseTarget, descend_from_seed, pose_errors
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas

__all__ = [
    "CartesianPath",
    "CartesianProblem",
    "CartesianStatus",
    "MotionVerdict",
    "cartesian_path",
    "path_fault",
    "sample_count",
    "sample_lines",
]

MIN_STEPS_FOR_JUMP = 10  # MoveIt's MIN_STEPS_FOR_JUMP_THRESH
IK_BUDGET_S = 0.05  # the most one sample's warm start may take


class CartesianStatus(str, Enum):
    """Why a Cartesian path ended where it did."""

    COMPLETE = "complete"
    NO_IK_SOLUTION = "no_ik_solution"
    JOINT_JUMP = "joint_jump"
    COLLISION = "collision"
    TOO_CLOSE = "too_close"
    OUT_OF_LIMITS = "out_of_limits"


@dataclass(frozen=True)
class MotionVerdict:
    """A validator's word on the straight joint motions through some states: how many of the
    states lead a valid path from the first (all: valid), and why not."""

    kept: int
    status: CartesianStatus = CartesianStatus.COMPLETE
    message: str = ""


@dataclass(frozen=True)
class CartesianProblem:
    """The start, the link, the waypoints (4×4 poses, the frame IK reads) and the limits."""

    kinematics: PinKinematics
    link: str
    start: FloatArray
    waypoints: Sequence[FloatArray]
    max_step: float = 0.01
    max_rotation_step: float = 0.05
    jump_threshold: float = 0.0
    revolute_jump_threshold: float = 0.0
    prismatic_jump_threshold: float = 0.0
    position_tolerance: float = 1e-4
    orientation_tolerance: float = 1e-3
    validate_fn: Callable[[FloatArray], MotionVerdict] | None = None


@dataclass(frozen=True)
class CartesianPath:
    """The joint states reached (the start first), MoveIt's fraction, and why it stopped.

    `lines` (N, 2, 3) are the straight lines' end positions; `line_of[k]` the line state k
    was solved on (0 for the start)."""

    status: CartesianStatus
    states: FloatArray
    fraction: float
    lines: FloatArray
    line_of: np.ndarray
    message: str = ""
    notes: tuple[str, ...] = field(default=())


@dataclass(frozen=True)
class _Samples:
    poses: FloatArray  # (M, 4, 4), the start's pose excluded
    line: np.ndarray  # (M,) the line of each sample
    share: FloatArray  # (M,) how far along its line (k / n)
    lines: FloatArray  # (N, 2, 3)


def sample_count(
    start: FloatArray, waypoints: Sequence[FloatArray], max_step: float, max_rotation_step: float
) -> int:
    """How many samples `sample_lines` makes (cheap: no poses are built)."""
    poses = np.concatenate([np.asarray(start, dtype=float)[None], np.asarray(waypoints, float)])
    distances = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    turns = np.einsum("nij,nij->n", poses[:-1, :3, :3], poses[1:, :3, :3])  # trace(Aᵀ B)
    angles = np.arccos(np.clip((turns - 1.0) / 2.0, -1.0, 1.0))
    counts = np.maximum(np.ceil(distances / max_step - 1e-9), np.ceil(angles / max_rotation_step))
    return int(np.maximum(counts, 1).sum())


def sample_lines(
    start: FloatArray, waypoints: Sequence[FloatArray], max_step: float, max_rotation_step: float
) -> tuple[FloatArray, np.ndarray, FloatArray, FloatArray]:
    """Poses along the lines from `start` through `waypoints`: (poses, line, share, lines)."""
    poses, line, share, ends = [], [], [], []
    previous = np.asarray(start, dtype=float)
    for j, waypoint in enumerate(waypoints):
        target = np.asarray(waypoint, dtype=float)
        distance = float(np.linalg.norm(target[:3, 3] - previous[:3, 3]))
        rotations = Rotation.from_matrix(np.stack([previous[:3, :3], target[:3, :3]]))
        angle = float((rotations[0].inv() * rotations[1]).magnitude())
        n = max(1, math.ceil(distance / max_step - 1e-9), math.ceil(angle / max_rotation_step))
        t = np.arange(1, n + 1) / n
        pose = np.tile(np.eye(4), (n, 1, 1))
        pose[:, :3, :3] = Slerp([0.0, 1.0], rotations)(t).as_matrix()
        pose[:, :3, 3] = previous[:3, 3] + t[:, None] * (target[:3, 3] - previous[:3, 3])
        pose[-1] = target
        poses.append(pose)
        line.append(np.full(n, j))
        share.append(t)
        ends.append((previous[:3, 3], target[:3, 3]))
        previous = target
    return np.concatenate(poses), np.concatenate(line), np.concatenate(share), np.array(ends)


def cartesian_path(problem: CartesianProblem) -> CartesianPath:
    """The joint path along the problem's lines, as far as it goes (module docstring)."""
    kin = problem.kinematics
    start = np.asarray(problem.start, dtype=float)
    origin = kin.link_pose(start, kin.frame_id(problem.link))
    poses, line, share, lines = sample_lines(
        origin, problem.waypoints, problem.max_step, problem.max_rotation_step
    )
    samples = _Samples(poses, line, share, lines)
    states, status, message = _solve(problem, samples, start)
    notes: list[str] = []
    if status is CartesianStatus.COMPLETE and problem.jump_threshold > 0:
        states, status, message = _relative_jump(states, problem.jump_threshold, notes)
    if problem.validate_fn is not None:
        verdict = problem.validate_fn(states)
        if verdict.kept < len(states):
            states, status, message = states[: verdict.kept], verdict.status, verdict.message
    reached = len(states) - 1
    fraction = 0.0
    if reached > 0:
        fraction = float((line[reached - 1] + share[reached - 1]) / len(problem.waypoints))
    if status is CartesianStatus.COMPLETE:
        fraction = 1.0
    line_of = np.concatenate([[0], line[:reached]]).astype(np.int64)
    return CartesianPath(status, states, fraction, lines, line_of, message, tuple(notes))


def _solve(
    problem: CartesianProblem, samples: _Samples, start: FloatArray
) -> tuple[FloatArray, CartesianStatus, str]:
    """Warm-started IK through the samples, up to the first without a solution or a jump."""
    model = problem.kinematics.model
    revolute = _turning(model)
    states = [start]
    for k, pose in enumerate(samples.poses):
        target = PoseTarget(
            problem.link, pose, problem.position_tolerance, problem.orientation_tolerance
        )
        found = descend_from_seed(
            IkProblem(
                problem.kinematics, target, states[-1], budget_s=IK_BUDGET_S, hold_limits=True
            )
        )
        where = f"sample {k + 1} of {len(samples.poses)} (line {int(samples.line[k]) + 1})"
        if found is None:
            message = (
                f"no IK solution for {problem.link!r} within {problem.position_tolerance:g} m "
                f"and {problem.orientation_tolerance:g} rad at {where}, from the previous sample"
            )
            return np.array(states), CartesianStatus.NO_IK_SOLUTION, message
        jump = _absolute_jump(problem, found - states[-1], revolute)
        if jump:
            return np.array(states), CartesianStatus.JOINT_JUMP, f"{jump} at {where}"
        states.append(found)
    return np.array(states), CartesianStatus.COMPLETE, ""


def _turning(model: RobotModel) -> np.ndarray:
    """Which state values turn a joint (the others slide: prismatic joints, a base's x, y)."""
    turning = np.ones(model.dof, dtype=bool)
    turning[: min(2, model.arm_offset)] = False
    for joint in model.joints:
        if joint.index >= model.arm_offset and joint.kind == "prismatic":
            turning[joint.index] = False
    return turning


def _absolute_jump(problem: CartesianProblem, step: FloatArray, revolute: np.ndarray) -> str:
    """What jumps in `step` over the absolute thresholds (empty: nothing)."""
    names = problem.kinematics.model.state_names
    for threshold, which, unit in (
        (problem.revolute_jump_threshold, revolute, "rad"),
        (problem.prismatic_jump_threshold, ~revolute, "m"),
    ):
        if threshold <= 0:
            continue
        over = np.flatnonzero(which & (np.abs(step) > threshold))
        if len(over):
            d = int(over[0])
            return (
                f"{names[d]} jumps by {abs(float(step[d])):.4g} {unit}, over the threshold "
                f"of {threshold:g} {unit}"
            )
    return ""


def _relative_jump(
    states: FloatArray, jump_threshold: float, notes: list[str]
) -> tuple[FloatArray, CartesianStatus, str]:
    """MoveIt's relative check: the path up to the first step longer than `jump_threshold` ×
    the mean step (not checked on paths of fewer than MIN_STEPS_FOR_JUMP steps)."""
    steps = np.linalg.norm(segment_deltas(states, base=BaseType.FIXED), axis=1)
    if len(steps) < MIN_STEPS_FOR_JUMP:
        notes.append(
            f"jump_threshold is not checked on a path of {len(steps)} steps (fewer than "
            f"{MIN_STEPS_FOR_JUMP}, as MoveIt)"
        )
        return states, CartesianStatus.COMPLETE, ""
    limit = jump_threshold * float(steps.mean())
    over = np.flatnonzero(steps > limit)
    if not len(over):
        return states, CartesianStatus.COMPLETE, ""
    k = int(over[0])
    message = (
        f"a joint-space step of {steps[k]:.4g} at sample {k + 1} is over jump_threshold × the "
        f"mean step ({jump_threshold:g} × {steps.mean():.4g})"
    )
    return states[: k + 1], CartesianStatus.JOINT_JUMP, message


def path_fault(problem: CartesianProblem, states: FloatArray, line_of: np.ndarray) -> str:
    """Why `states` (the start first) is not a complete path of `problem` as `cartesian_path`
    would answer it (empty: it is one): one state per sample, solved on the sample's line, each
    within the IK tolerances of its sample, no jump over the thresholds. A stored path is held
    to this before it serves, so that its word (an import's, a tampered row's) is never taken;
    the scene is the validator's to judge, not this."""
    kin = problem.kinematics
    frame = kin.frame_id(problem.link)
    states = np.asarray(states, dtype=float)
    start = np.asarray(problem.start, dtype=float)
    if states.ndim != 2 or len(states) < 2 or not np.array_equal(states[0], start):
        return "the path does not begin at its start"
    poses, line = sample_lines(
        kin.link_pose(start, frame), problem.waypoints, problem.max_step, problem.max_rotation_step
    )[:2]
    if len(states) != len(poses) + 1:
        return f"{len(states) - 1} states for {len(poses)} samples"
    if not np.array_equal(np.asarray(line_of), np.concatenate([[0], line])):
        return "a state is not on the line of its sample"
    tolerances = np.array([problem.position_tolerance, problem.orientation_tolerance])
    for k, pose in enumerate(poses):
        errors = pose_errors(kin, frame, states[k + 1], pin.SE3(pose))
        if np.any(np.array(errors) > tolerances):
            return f"state {k + 1} is off its sample by {errors[0]:.3g} m, {errors[1]:.3g} rad"
    revolute = _turning(kin.model)
    for k, step in enumerate(np.diff(states, axis=0)):
        jump = _absolute_jump(problem, step, revolute)
        if jump:
            return f"{jump} at sample {k + 1}"
    if problem.jump_threshold > 0:
        message = _relative_jump(states, problem.jump_threshold, [])[2]
        if message:
            return message
    return ""
