"""Measuring how far a certified path's interior stays from each scene object, for its
certificate (`certificates.py`: an object that later moves by less is not proved again).

The path is sampled as its validator samples it; at each sample k every (element, object) row
whose element ball comes within `CAP` gets coal's exact distance as its lower bound L_k (every
other row counts as `CAP`, still a lower bound; pairs the scene allows are not rows, as for the
validator). Between samples k and k + 1 the element moves by at most M_k (the certifier's whole-
element bound), so the distance is at least (L_k + L_{k+1} − M_k) / 2 there (`certify.py`); an
object's clearance is the least of those over every interval and element. An object no row
reaches gets CAP − max M_k / 2, the same bound for L = CAP throughout.
"""

from __future__ import annotations

import numpy as np

from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.certificates import ObjectClearance, shape_digests
from trajcache.geometry.validation.end_clearance import CAP, motion_tables
from trajcache.geometry.validation.envelope import Envelope, envelope_of
from trajcache.geometry.validation.sampling import interpolate
from trajcache.geometry.validation.validator import TrajectoryValidator

__all__ = ["MAX_KEPT", "interior_bounds"]

MAX_KEPT = 512  # objects whose clearance a certificate keeps (the scene's first)


def interior_bounds(
    validator: TrajectoryValidator, states: FloatArray, scene: Scene, *, sweep: bool
) -> tuple[dict[str, ObjectClearance], Envelope | None]:
    """The clearance of the motion through `states` (n ≥ 2) from each of `scene`'s objects (the
    scene `validator` checks), by object id, with the object's shape digest and pose; and with
    `sweep`, the motion's swept envelope (`envelope.py`), from the same samples and forward
    kinematics."""
    checker, model = validator.checker, validator.model
    robot = checker.robot
    samples = interpolate(states, model, validator.resolution, validator.subdivision)
    posed = Posed.build(robot, samples)
    steps = robot.motion.steps(segment_deltas(samples, base=model.base))
    motion = steps @ motion_tables(robot)[0].T  # (K − 1, E)
    envelope = envelope_of(posed, motion) if sweep else None
    objects = scene.objects[:MAX_KEPT]
    if not objects:
        return {}, envelope
    clearance = np.full(len(objects), CAP - float(motion.max(initial=0.0)) / 2.0)
    n, e = len(samples), len(robot.radius)
    rows = checker.clearance.scene_ball_rows(posed, np.full((n, e), CAP))
    rows = rows[rows[:, 2] < len(objects)]
    if len(rows):
        near, column = np.unique(rows[:, 2], return_inverse=True)
        at = np.full((n, e, len(near)), CAP)
        exact = checker.narrow.scene_exact(posed, rows, CAP)
        at[rows[:, 0], rows[:, 1], column] = np.minimum(exact, CAP)
        between = (at[:-1] + at[1:] - motion[:, :, None]) / 2.0
        clearance[near] = np.minimum(clearance[near], between.min(axis=(0, 1)))
    shapes = shape_digests(scene)
    return {
        obj.id: ObjectClearance(shapes[obj.id], np.array(obj.pose, dtype=float), float(c))
        for obj, c in zip(objects, clearance, strict=True)
    }, envelope
