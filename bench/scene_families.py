"""Seeded planning problems around a real robot, in four families after MotionBenchMaker's.

Every scene stands in front of (+x) the robot, its sizes and positions drawn from a seed and
scaled to the robot's reach R, measured from its shoulder S (the first revolute planning joint)
to the end effector over random states by forward kinematics:

- `table`: a table top below the shoulder and in front of the arm (legs when it stands above the
  base's floor), with up to three boxes and cylinders on it; goals just above the top.
- `shelf`: a shelf of two or three boards, two sides and a back; goals inside a compartment.
- `box`: an open box (bottom and four walls) below the shoulder; goals inside it.
- `cage`: vertical bars all around the shoulder and one or two rings of horizontal bars between
  them; goals inside the cage in front of the arm.

A problem is (scene objects in the service's native payload, start, goal). Start and goal are
found by rejection sampling within the planning joints' limits (an unbounded joint in [−π, π]):
free by the independent check (`dense_mesh.MeshChecker`: the scene and every self pair the SRDF
does not disable, minus adjacent bodies). The goal is preferably one whose end effector lies in
the family's region (GOAL_TRIES tries), else any free state. A scene that touches the robot's
standing body is drawn again. A planar base (tiago) stays at the origin, heading 0, in the start
and the goal of every family: the problems are arm problems, and the scene is scaled to the arm.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dense_mesh import FloatArray, MeshChecker

FAMILIES = ("table", "shelf", "box", "cage")
SCENE_TRIES, STATE_TRIES, GOAL_TRIES = 20, 500, 3000
REACH_SAMPLES = 1000


@dataclass(frozen=True)
class Workspace:
    """Where the arm reaches (its shoulder and its reach, m) and the bounds states are drawn in."""

    shoulder: FloatArray
    reach: float
    lower: FloatArray  # the limits, with an unbounded value drawn in [−π, π]
    upper: FloatArray
    planar: bool  # a planar base, which stays at the origin


@dataclass(frozen=True)
class Region:
    """An axis-aligned box of interesting end-effector positions."""

    lo: FloatArray
    hi: FloatArray

    def contains(self, point: FloatArray) -> bool:
        """Whether `point` lies in the box."""
        return bool(np.all(point >= self.lo) and np.all(point <= self.hi))


@dataclass(frozen=True)
class Problem:
    """One planning problem: a scene, a free start and a free goal (service state order)."""

    family: str
    index: int
    objects: tuple[dict[str, Any], ...]
    start: FloatArray
    goal: FloatArray
    goal_in_region: bool


def sample_state(ws: Workspace, rng: np.random.Generator) -> FloatArray:
    """A random state within the bounds; a planar base stays at the origin."""
    state = rng.uniform(ws.lower, ws.upper)
    if ws.planar:
        state[:3] = 0.0
    return state


def workspace(
    checker: MeshChecker,
    seed: int = 0,
    lower: FloatArray | None = None,
    upper: FloatArray | None = None,
) -> Workspace:
    """The shoulder and the reach, from forward kinematics at random states within the checker's
    limits (narrowed to `lower` and `upper` when given)."""
    lo = checker.lower if lower is None else np.maximum(checker.lower, lower)
    hi = checker.upper if upper is None else np.minimum(checker.upper, upper)
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    rest = np.clip(np.zeros(len(lo)), lo, hi)
    names = checker.robot.joint_names
    first = next(n for n, p in zip(names, checker.prismatic, strict=True) if not p)
    shoulder = checker.joint_position(rest, first)
    rng = np.random.default_rng(seed)
    ws = Workspace(shoulder, 0.0, lo, hi, checker.planar)
    tips = np.array([checker.tip_position(sample_state(ws, rng)) for _ in range(REACH_SAMPLES)])
    reach = float(np.max(np.linalg.norm(tips - shoulder, axis=1)))
    return Workspace(shoulder, reach, lo, hi, checker.planar)


# --- scene objects ------------------------------------------------------------------------------


def _rounded(values: Any) -> list[float]:
    return [round(float(v), 4) for v in values]


def _box(oid: str, centre: Any, size: Any) -> dict[str, Any]:
    pose = {"position": _rounded(centre), "orientation": [0.0, 0.0, 0.0, 1.0]}
    return {"id": oid, "type": "box", "size": _rounded(size), "pose": pose}


def _bar(oid: str, a: Any, b: Any, radius: float) -> dict[str, Any]:
    """A cylinder from point a to point b."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = (b - a) / np.linalg.norm(b - a)
    turn = np.cross([0.0, 0.0, 1.0], axis)
    angle = float(np.arccos(np.clip(axis[2], -1.0, 1.0)))
    if np.linalg.norm(turn) < 1e-9:
        turn = np.array([1.0, 0.0, 0.0])
    q = [*(np.sin(angle / 2) * turn / np.linalg.norm(turn)), np.cos(angle / 2)]
    pose = {"position": _rounded((a + b) / 2), "orientation": [float(v) for v in q]}
    size = _rounded([radius, np.linalg.norm(b - a)])
    return {"id": oid, "type": "cylinder", "size": size, "pose": pose}


def _table(ws: Workspace, rng: np.random.Generator) -> tuple[list[dict[str, Any]], Region]:
    s, r, u = ws.shoulder, ws.reach, rng.uniform
    x0, depth, width = s[0] + u(0.25, 0.4) * r, u(0.5, 0.8) * r, u(0.9, 1.4) * r
    cy, top = s[1] + u(-0.2, 0.2) * r, s[2] - u(0.15, 0.55) * r
    objects = [_box("table_top", (x0 + depth / 2, cy, top - 0.015), (depth, width, 0.03))]
    if top > 0.15:  # legs down to the base's floor
        for k, (fx, fy) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
            x, y = x0 + 0.04 + fx * (depth - 0.08), cy - width / 2 + 0.04 + fy * (width - 0.08)
            objects.append(_bar(f"table_leg_{k}", (x, y, 0.0), (x, y, top - 0.03), 0.02))
    for k in range(int(rng.integers(0, 4))):
        size = u(0.04, 0.12, 3) * r
        x, y = (
            u(x0 + size[0], x0 + depth - size[0]),
            u(cy - width / 2 + size[1], cy + width / 2 - size[1]),
        )
        if rng.random() < 0.5:
            objects.append(_box(f"item_{k}", (x, y, top + size[2] / 2), size))
        else:
            objects.append(_bar(f"item_{k}", (x, y, top), (x, y, top + size[2]), size[0] / 2))
    lo = np.array([x0 + 0.03, cy - width / 2 + 0.03, top + 0.03])
    return objects, Region(lo, np.array([x0 + depth - 0.03, cy + width / 2 - 0.03, top + 0.3 * r]))


def _shelf(ws: Workspace, rng: np.random.Generator) -> tuple[list[dict[str, Any]], Region]:
    s, r, u, t = ws.shoulder, ws.reach, rng.uniform, 0.02
    d, depth, width = s[0] + u(0.4, 0.6) * r, u(0.25, 0.4) * r, u(0.7, 1.1) * r
    cy, gap, z0 = s[1] + u(-0.25, 0.25) * r, u(0.25, 0.35) * r, s[2] - u(0.35, 0.6) * r
    boards = int(rng.integers(2, 4))
    height = (boards - 1) * gap
    cx = d + depth / 2
    objects = [
        _box(f"shelf_board_{k}", (cx, cy, z0 + k * gap), (depth, width, t)) for k in range(boards)
    ]
    for side in (-1, 1):
        objects.append(
            _box(
                f"shelf_side_{side:+d}",
                (cx, cy + side * width / 2, z0 + height / 2),
                (depth, t, height + t),
            )
        )
    objects.append(_box("shelf_back", (d + depth, cy, z0 + height / 2), (t, width, height + t)))
    k = int(rng.integers(0, boards - 1))  # the compartment of the goal
    lo = np.array([d + 0.03, cy - width / 2 + 0.05, z0 + k * gap + 0.03])
    return objects, Region(
        lo, np.array([d + depth - 0.05, cy + width / 2 - 0.05, z0 + (k + 1) * gap - 0.05])
    )


def _open_box(ws: Workspace, rng: np.random.Generator) -> tuple[list[dict[str, Any]], Region]:
    s, r, u, t = ws.shoulder, ws.reach, rng.uniform, 0.015
    cx, cy = s[0] + u(0.4, 0.6) * r, s[1] + u(-0.3, 0.3) * r
    a, b, h = u(0.3, 0.45) * r, u(0.3, 0.45) * r, u(0.15, 0.3) * r
    zb = s[2] - u(0.45, 0.75) * r
    objects = [
        _box("box_bottom", (cx, cy, zb - t / 2), (a + 2 * t, b + 2 * t, t)),
        _box("box_wall_front", (cx - a / 2 - t / 2, cy, zb + h / 2), (t, b + 2 * t, h)),
        _box("box_wall_back", (cx + a / 2 + t / 2, cy, zb + h / 2), (t, b + 2 * t, h)),
        _box("box_wall_left", (cx, cy + b / 2 + t / 2, zb + h / 2), (a, t, h)),
        _box("box_wall_right", (cx, cy - b / 2 - t / 2, zb + h / 2), (a, t, h)),
    ]
    lo = np.array([cx - a / 2 + 0.02, cy - b / 2 + 0.02, zb + 0.03])
    return objects, Region(lo, np.array([cx + a / 2 - 0.02, cy + b / 2 - 0.02, zb + h]))


def _cage(ws: Workspace, rng: np.random.Generator) -> tuple[list[dict[str, Any]], Region]:
    s, r, u = ws.shoulder, ws.reach, rng.uniform
    rho, n, radius = u(0.55, 0.8) * r, int(rng.integers(6, 11)), u(0.01, 0.025)
    angles = 2 * np.pi * np.arange(n) / n + u(-0.15, 0.15, n) + u(0, 2 * np.pi)
    feet = [s[:2] + rho * np.array([np.cos(a), np.sin(a)]) for a in angles]
    low, high = s[2] - 0.7 * r, s[2] + 0.5 * r
    objects = [_bar(f"cage_bar_{k}", (*p, low), (*p, high), radius) for k, p in enumerate(feet)]
    for ring in range(int(rng.integers(1, 3))):
        z = u(s[2] - 0.3 * r, s[2] + 0.4 * r)
        for k in range(n):
            a, b = feet[k], feet[(k + 1) % n]
            objects.append(_bar(f"cage_ring_{ring}_{k}", (*a, z), (*b, z), radius))
    lo = np.array([s[0] + 0.25 * r, s[1] - 0.4 * rho, s[2] - 0.4 * r])
    return objects, Region(lo, np.array([s[0] + rho - 0.1, s[1] + 0.4 * rho, s[2] + 0.4 * r]))


DRAW = {"table": _table, "shelf": _shelf, "box": _open_box, "cage": _cage}


# --- problems -----------------------------------------------------------------------------------


def free_state(checker: MeshChecker, ws: Workspace, rng: np.random.Generator) -> FloatArray | None:
    """A random state free in the current scene, or None after STATE_TRIES tries."""
    for _ in range(STATE_TRIES):
        state = sample_state(ws, rng)
        if checker.is_free(state):
            return state
    return None


def goal_state(
    checker: MeshChecker,
    ws: Workspace,
    rng: np.random.Generator,
    region: Region,
    clearance: tuple[float, float] | None = None,
) -> tuple[FloatArray | None, bool]:
    """A free state with the end effector in `region` if one turns up, else any free state.

    With `clearance` (low, high), only a goal in the region whose least distance to the scene
    lies within it (m), as tight as MotionBenchMaker's goals in shelves and boxes; None when
    none turns up."""
    for _ in range(GOAL_TRIES):
        state = sample_state(ws, rng)
        if region.contains(checker.tip_position(state)) and checker.is_free(state):
            if clearance is None:
                return state, True
            if clearance[0] <= checker.scene_clearance(state) <= clearance[1]:
                return state, True
    if clearance is not None:
        return None, False
    return free_state(checker, ws, rng), False


def generate_problem(
    checker: MeshChecker,
    ws: Workspace,
    family: str,
    index: int,
    seed: int,
    clearance: tuple[float, float] | None = None,
) -> Problem | None:
    """Problem `index` of `family` (seeded); None when no scene of SCENE_TRIES gave free states
    (with `clearance`, a goal that near the scene: `goal_state`).

    Leaves `checker` set to the problem's scene."""
    rng = np.random.default_rng([seed, FAMILIES.index(family), index])
    for _ in range(SCENE_TRIES):
        objects, region = DRAW[family](ws, rng)
        checker.set_scene(objects)
        if not checker.base_clear():
            continue
        start = free_state(checker, ws, rng)
        if start is None:
            continue
        goal, in_region = goal_state(checker, ws, rng, region, clearance)
        if goal is not None:
            return Problem(family, index, tuple(objects), start, goal, in_region)
    return None
