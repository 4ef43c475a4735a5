"""The safety soak's geometry: judging a returned trajectory densely, and placing an obstacle
into the path of a cached trajectory (on the robot part that moves farthest, or just grazing it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.dense import DenseChecker
from trajcache.cache.metric import wrap_angle
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene

MIN_MARGIN = 0.03  # m: from an obstacle to the bounding spheres of the robot at the endpoints


@dataclass
class Verdict:
    """The dense check of one returned trajectory."""

    collides: bool
    out_of_limits: bool
    misjoined: bool  # does not run from the request's start to its goal
    samples: int
    contacts: tuple[str, ...] = ()

    @property
    def unsafe(self) -> bool:
        """Whether a robot following the trajectory would be in danger."""
        return self.collides or self.out_of_limits or self.misjoined


def _wrapped(diff: FloatArray) -> FloatArray:
    """A difference of planar-base states with the base angle taking the short way."""
    out = np.array(diff, dtype=float)
    out[2] = wrap_angle(out[2])
    return out


def judge(
    checker: DenseChecker, scene: Scene, states: FloatArray, start: FloatArray, goal: FloatArray
) -> Verdict:
    """Check a returned trajectory densely in `scene` and against the request's endpoints."""
    states = np.asarray(states, dtype=float)
    verdict = checker.check(states, scene.hash, scene_to_payload(scene))
    misjoined = any(
        float(np.max(np.abs(_wrapped(s - w)))) > 1e-6
        for s, w in ((states[0], start), (states[-1], goal))
    )
    contacts = tuple(sorted(f"{a}–{b}" for a, b in verdict.contacts))
    return Verdict(
        verdict.collides, verdict.limit_samples > 0, misjoined, verdict.samples, contacts
    )


def _centres(checker: DenseChecker, states: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(N, P, 3) world centres of every robot primitive at each state, and (P,) their radii."""
    links = checker.link_poses(np.asarray(states, dtype=float))
    centres = np.stack([(links[p.link] @ p.origin)[:, :3, 3] for p in checker.primitives], axis=1)
    return centres, np.array([p.radius for p in checker.primitives])


def path_obstacle(
    checker: DenseChecker, path: FloatArray, oid: str, rng: np.random.Generator
) -> dict[str, Any] | None:
    """A small sphere on a robot link at an interior state of `path`, clear of its endpoints.

    The sphere's centre is a primitive's centre (inside the link) at the dense sample and
    primitive whose centre lies farthest from the robot at the path's first and last state;
    None when the path moves too little for that.
    """
    dense = checker.interpolate(path)
    if len(dense) < 5:
        return None
    centres, radius = _centres(checker, dense)
    ends = centres[[0, -1]].reshape(-1, 3)  # every primitive at both endpoints
    ends_r = np.tile(radius, 2)
    inner = centres[len(dense) // 8 : len(dense) - len(dense) // 8]  # (M, P, 3)
    gap = np.linalg.norm(inner[:, :, None, :] - ends[None, None], axis=-1) - ends_r  # (M, P, 2P)
    margin = gap.min(axis=-1)
    size = float(rng.uniform(0.03, 0.05))
    if margin.max() < size + MIN_MARGIN:
        return None
    s, p = np.unravel_index(int(np.argmax(margin)), margin.shape)
    return sphere(oid, inner[s, p], size)


def sphere(oid: str, centre: FloatArray, radius: float) -> dict[str, Any]:
    """A sphere as a scene object payload."""
    return {
        "id": oid,
        "type": "sphere",
        "size": [round(float(radius), 4)],
        "pose": {"position": [float(v) for v in centre], "orientation": [0.0, 0.0, 0.0, 1.0]},
    }


def grazing_radius(
    checker: DenseChecker, paths: list[FloatArray], centre: FloatArray, high: float
) -> float | None:
    """The smallest radius (to 0.5 mm) of a sphere at `centre` that every path touches.

    None when a sphere of radius `high` does not touch them all.
    """

    def touches(radius: float) -> bool:
        probe = {"objects": [sphere("probe", centre, radius)], "env": {}}
        key = f"probe {centre.tolist()} {radius!r}"
        verdicts = (checker.check(path, key, probe) for path in paths)
        return all(any(obj == "probe" for _, obj in v.contacts) for v in verdicts)

    low = 0.0
    if not touches(high):
        return None
    while high - low > 5e-4:
        mid = (low + high) / 2
        low, high = (low, mid) if touches(mid) else (mid, high)
    return high
