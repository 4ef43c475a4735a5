"""A certified path's swept envelope: balls whose union holds every point of the robot along
its interior, kept with its certificate (`certificates.py`) so that an object the certificate
has never seen is certified clear of the interior in O(balls), without the certifier.

The argument. The interior is sampled as its validator samples it (samples k = 0 … n). At each
sample, every collision element e of the robot (attached objects included: they are elements of
the checked model) lies within r_e of its origin c_k,e (`Shape.bounding_radius`, the certifier's
level-1 balls). Between samples k and k + 1 no point of the element moves further than M_k,e
from where it was at sample k (the certifier's whole-element bound: `end_clearance.motion_tables`,
configuration-independent). So during that interval every point of e lies in the ball
B(c_k,e, r_e + M_k,e). The envelope groups the intervals of a chunk (`CHUNK` consecutive ones)
per element into one ball B(m, R) that holds each of theirs: m the middle of their centres'
bounding box, R = max over the chunk's intervals of |c_k,e − m| + r_e + M_k,e. The union over
chunks and elements holds the robot along the whole interior, samples included.

An object is clear of a ball B(m, R) when its distance from m is more than R. Every object lies
within its own axis-aligned box [−h, h] about its origin (`Shape.half_extents`, in its frame)
and within its bounding sphere (radius ρ about its origin), so its distance from m is at least
the larger of |max(|Rᵀ(m − t)| − h, 0)| and |m − t| − ρ, for its pose (R, t). Where that exceeds
R + `EXACT_MARGIN` (the narrow phase's own margin) for every ball, no point of the robot along
the interior is in the object: the statement (ii) of `certificates.py` holds for it, whatever
its pose, as if the certifier had proved it. It says nothing of the first and last segments,
which a hit proves anew (`validate_with_certificate`), nor of self-collision and the limits,
which the certificate already holds.

Storage is bounded: at most `MAX_BALLS` balls (larger chunks for longer paths), float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.collision.bodies import Posed
from trajcache.geometry.collision.narrow import EXACT_MARGIN
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import segment_deltas
from trajcache.geometry.scene.scene import SceneObject
from trajcache.geometry.validation.end_clearance import motion_tables
from trajcache.geometry.validation.sampling import interpolate
from trajcache.geometry.validation.validator import TrajectoryValidator

__all__ = ["CHUNK", "MAX_BALLS", "Envelope", "envelope_of", "swept_envelope"]

CHUNK = 8  # intervals between samples whose balls one envelope ball holds, per element
MAX_BALLS = 512  # balls an envelope keeps at most (chunks grow to stay within it): 16 KiB


@dataclass(frozen=True, eq=False)
class Envelope:
    """Balls (B, 3) centres and (B,) radii whose union holds the robot along an interior."""

    centres: FloatArray
    radii: FloatArray

    def clear_of(self, obj: SceneObject) -> bool:
        """Whether `obj` is certified clear of every ball (module docstring)."""
        if not len(self.radii):
            return True
        pose = np.asarray(obj.pose, dtype=float)
        offset = self.centres - pose[:3, 3]
        local = offset @ pose[:3, :3]  # each row Rᵀ(m − t)
        outside = np.maximum(np.abs(local) - obj.shape.half_extents(), 0.0)
        gap = np.maximum(
            np.linalg.norm(outside, axis=1),
            np.linalg.norm(offset, axis=1) - obj.shape.bounding_radius(),
        )
        return bool(np.all(gap - self.radii > EXACT_MARGIN))

    def to_bytes(self) -> bytes:
        """float64 rows (x, y, z, radius), little-endian."""
        rows = np.column_stack([self.centres, self.radii]).astype("<f8")
        return rows.tobytes()

    @classmethod
    def from_bytes(cls, data: bytes) -> Envelope:
        """The envelope `to_bytes` wrote."""
        rows = np.frombuffer(data, dtype="<f8").reshape(-1, 4).astype(np.float64)
        return cls(np.ascontiguousarray(rows[:, :3]), np.ascontiguousarray(rows[:, 3]))


def swept_envelope(validator: TrajectoryValidator, states: FloatArray) -> Envelope:
    """The envelope of the motion through `states` (n ≥ 2) of the robot `validator` checks,
    sampled as it samples them (module docstring)."""
    robot, model = validator.checker.robot, validator.model
    samples = interpolate(states, model, validator.resolution, validator.subdivision)
    steps = robot.motion.steps(segment_deltas(samples, base=model.base))
    return envelope_of(Posed.build(robot, samples), steps @ motion_tables(robot)[0].T)


def envelope_of(posed: Posed, motion: FloatArray) -> Envelope:
    """The envelope of posed samples (K + 1) whose elements move by at most `motion` (K, E)
    between consecutive ones (the whole-element bounds of `motion_tables`)."""
    centres = posed.centres[:-1]  # (K, E, 3): each interval's start
    reach = posed.robot.radius + motion  # (K, E)
    intervals, elements = reach.shape
    if not intervals:
        return Envelope(np.zeros((0, 3)), np.zeros(0))
    chunk = max(CHUNK, math.ceil(intervals * elements / MAX_BALLS))
    pad = -intervals % chunk  # the last interval again: no chunk's min, max or reach changes
    centres = np.concatenate([centres, np.repeat(centres[-1:], pad, axis=0)])
    reach = np.concatenate([reach, np.repeat(reach[-1:], pad, axis=0)])
    parts = centres.reshape(-1, chunk, elements, 3)  # (chunks, chunk, E, 3)
    middle = (parts.min(axis=1) + parts.max(axis=1)) / 2.0  # (chunks, E, 3)
    spread = np.linalg.norm(parts - middle[:, None], axis=3)  # (chunks, chunk, E)
    radii = (spread + reach.reshape(-1, chunk, elements)).max(axis=1)  # (chunks, E)
    return Envelope(middle.reshape(-1, 3), radii.reshape(-1))
