"""The Panda row's paths in one generated problem: straight, detour and grazing (key states).

- `straight`: start → goal;
- `detour`: start → a free intermediate state → goal, as a planner's waypoint (near the middle
  of the straight motion, each joint moved by N(0, DETOUR_SIGMA) rad; any free state when none
  of DETOUR_TRIES is free);
- `grazing`: when the straight motion collides, a detour the dense check finds free (of up to
  GRAZE_TRIES waypoints drawn as above) pulled back toward the straight motion's middle by
  bisection (GRAZE_STEPS halvings) to the last waypoint whose path the dense check finds free:
  a path that passes an obstacle at about the dense check's resolution, as a shortcut planned
  path does.

"Free" is the independent dense check's verdict (`dense_mesh.MeshChecker`, in the problem's
scene), never the validator's.
"""

from __future__ import annotations

import numpy as np

from dense_mesh import FloatArray, MeshChecker
from scene_families import Problem, Workspace, free_state

DETOUR_SIGMA, DETOUR_TRIES, GRAZE_TRIES, GRAZE_STEPS = 0.3, 50, 20, 10
KINDS = ("straight", "detour", "grazing")


def paths_of(
    dense: MeshChecker, ws: Workspace, problem: Problem, rng: np.random.Generator
) -> list[tuple[str, FloatArray]]:
    """The problem's (kind, key states) paths; `dense` must hold the problem's scene."""
    paths = [("straight", np.stack([problem.start, problem.goal]))]
    mid = waypoint(dense, ws, problem, rng)
    mid = free_state(dense, ws, rng) if mid is None else mid
    if mid is not None:
        paths.append(("detour", np.stack([problem.start, mid, problem.goal])))
    near = grazing(dense, ws, problem, rng)
    if near is not None:
        paths.append(("grazing", near))
    return paths


def waypoint(
    dense: MeshChecker, ws: Workspace, problem: Problem, rng: np.random.Generator
) -> FloatArray | None:
    """A free state near the middle of the problem's straight motion, or None (DETOUR_TRIES)."""
    delta = problem.goal - problem.start
    for _ in range(DETOUR_TRIES):
        mid = problem.start + rng.uniform(0.3, 0.7) * delta
        mid = np.clip(mid + rng.normal(0.0, DETOUR_SIGMA, len(mid)), ws.lower, ws.upper)
        if dense.is_free(mid):
            return mid
    return None


def dense_collides(dense: MeshChecker, key: FloatArray) -> tuple[bool, int]:
    """Whether a dense sample of the path is in contact, and how many samples were checked."""
    samples = dense.interpolate(key)
    for k, state in enumerate(samples):
        if not dense.is_free(state):
            return True, k + 1
    return False, len(samples)


def grazing(
    dense: MeshChecker, ws: Workspace, problem: Problem, rng: np.random.Generator
) -> FloatArray | None:
    """A free detour pulled toward the straight motion until it nearly touches; None unless the
    straight motion collides and one of GRAZE_TRIES waypoints gives a free detour."""
    middle = (problem.start + problem.goal) / 2.0
    if not dense_collides(dense, np.stack([problem.start, problem.goal]))[0]:
        return None
    for _ in range(GRAZE_TRIES):
        mid = waypoint(dense, ws, problem, rng)
        if mid is not None and not dense_collides(dense, _via(problem, middle, mid, 1.0))[0]:
            return _pulled(dense, problem, middle, mid)
    return None


def _via(problem: Problem, middle: FloatArray, mid: FloatArray, toward_mid: float) -> FloatArray:
    return np.stack([problem.start, middle + toward_mid * (mid - middle), problem.goal])


def _pulled(
    dense: MeshChecker, problem: Problem, middle: FloatArray, mid: FloatArray
) -> FloatArray:
    """Bisection between the colliding straight motion (0) and the free detour (1)."""
    hit, free = 0.0, 1.0
    for _ in range(GRAZE_STEPS):
        half = (hit + free) / 2.0
        if dense_collides(dense, _via(problem, middle, mid, half))[0]:
            hit = half
        else:
            free = half
    return _via(problem, middle, mid, free)
