"""Certificates kept with a trajectory: what a valid verdict proved, so that a later validation
proves only what is new.

The argument. A path is valid in a scene when (i) every sample is within the joint limits,
(ii) every segment is certified against every scene object and (iii) every segment is certified
free of self-collision. The certifier settles each (element, object) pair and each pair of
elements on its own (`certify.py`), so its verdict is the conjunction of one statement per
object and one about the robot itself. Each statement depends only on:
- the states, to the bit (`path_digest`);
- the checked model: its id names the robot with its held joints, attached objects and allowed
  link pairs (`scene/variant.py`); (i) and (iii) depend on nothing else;
- the validator's settings and the certifier's code: the stamp (`stamp_of`, with
  `stamp.certifier_digest`); a change of either is another stamp;
- for (ii), the object itself: its shape, its exact pose (float64 bytes) and the names the scene
  allows it to touch (`object_digest`). Its id and the other objects do not enter.

A certificate names a path, a variant, a stamp and the object digests the path was certified
against. It is written only after a valid verdict, so (i) and (iii) hold for it as well. In
another scene, the statements of the objects whose digests it holds are the very statements
that were proved: the path is valid there if it is valid against the other objects alone, which
a scene-only validation of those objects decides (`CollisionChecker`'s `self_collision=False`).
An object that left the scene drops a statement, which cannot make a valid path invalid.

A cached path is served adapted: new first and last states, its interior kept. A certificate
names the interior (every state but the first and last), so the first and last segments are
validated in full, and the interior only against the objects its certificate lacks
(`validate_with_certificate`). With `audit`, every verdict a certificate shortened is proved
again in full, and a disagreement raises `CertificateDisagreement`: the property tests run so.

An object that moved. A certificate also keeps, per object id, a lower bound C on the distance
the robot kept from the object along the interior (`object_clearance.py` measures it, off the
request path), with the object's shape digest (its kind, sizes, mesh and allowed names: its
digest without the pose) and exact pose. An object of the current scene whose digest the
certificate lacks, but whose id, shape digest are the same, and which moved by δ < C, needs no
new proof: a rigid move from pose T to T' moves no point of the object further than
δ = |t' − t| + 2·sin(θ/2)·r, where θ is the angle of R'Rᵀ and r the radius of the smallest
sphere about the object's origin that holds it (`moved_by`); every point of the robot along the
interior stayed at least C from every point of the object at T, so it stays at least C − δ > 0
from it at T' (distance is 1-Lipschitz in each point). Its allowed names are in the shape
digest, so the pairs the statement excludes are the same. Not used: swept envelopes.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from trajcache.core.lru import LRU
from trajcache.geometry.model.shapes import FloatArray, ShapeKind
from trajcache.geometry.scene.scene import Scene, SceneObject
from trajcache.geometry.validation.stamp import certifier_digest
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
)

__all__ = [
    "CertificateDisagreement",
    "CertificateKey",
    "CertificateUse",
    "Held",
    "ObjectClearance",
    "moved_by",
    "moves_by",
    "object_digest",
    "object_digests",
    "path_digest",
    "shape_digest",
    "shape_digests",
    "stamp_of",
    "validate_with_certificate",
]

MAX_OBJECTS = 4096  # object digests kept per certificate (the current scene's first)
_SCENE_DIGESTS: LRU[tuple[str, bool], dict[str, str]] = LRU(capacity=256)  # by content hash


class CertificateDisagreement(AssertionError):
    """An audited verdict that a certificate shortened differs from the full one."""


@dataclass(frozen=True)
class CertificateKey:
    """What a certificate is about: a path (the digest of an interior), under a model variant
    and a stamp."""

    variant: str  # the checked model's id
    stamp: str  # `stamp_of` the validator's settings
    path: str  # `path_digest` of the interior states


@dataclass(frozen=True)
class CertificateUse:
    """How a validation used a certificate: the scene's objects, those proved again, those
    whose move its clearances covered, and those clear of its swept envelope."""

    objects: int
    reproved: int
    moved: int = 0
    clear: int = 0


def stamp_of(settings_key: tuple[object, ...]) -> str:
    """The certifier's digest and the validator's settings, hashed together."""
    digest = hashlib.sha256(certifier_digest().encode())
    digest.update(b"\0" + repr(settings_key).encode())
    return digest.hexdigest()


def path_digest(states: FloatArray) -> str:
    """SHA-256 of the exact float64 values of (n, D) states, with their shape."""
    array = np.ascontiguousarray(states, dtype=np.float64)
    digest = hashlib.sha256(repr(array.shape).encode())
    digest.update(array.tobytes())
    return digest.hexdigest()


def object_digest(obj: SceneObject, touches: Iterable[str] = ()) -> str:
    """SHA-256 of what an object's statement depends on: its shape (kind, exact sizes, mesh
    vertices and faces), its exact pose, and the names it may touch; not its id. (Its
    `shape_digest` hashed again with the pose.)"""
    return _posed(shape_digest(obj, touches), obj)


def shape_digest(obj: SceneObject, touches: Iterable[str] = ()) -> str:
    """`object_digest` without the pose: what an object's clearance is about besides where it
    is."""
    shape = obj.shape
    digest = hashlib.sha256(shape.kind.value.encode())
    digest.update(np.asarray(shape.size, dtype=np.float64).tobytes())
    if shape.kind is ShapeKind.MESH:
        assert shape.vertices is not None and shape.faces is not None
        digest.update(np.ascontiguousarray(shape.vertices, dtype=np.float64).tobytes())
        digest.update(np.ascontiguousarray(shape.faces, dtype=np.int64).tobytes())
    digest.update(repr(sorted(touches)).encode())
    return digest.hexdigest()[:32]


def _posed(shape: str, obj: SceneObject) -> str:
    digest = hashlib.sha256(shape.encode())
    digest.update(np.ascontiguousarray(obj.pose, dtype=np.float64).tobytes())
    return digest.hexdigest()[:32]


def moved_by(before: FloatArray, after: FloatArray, radius: float) -> float:
    """The most a point within `radius` of a body's origin moves when its pose changes from
    `before` to `after` (4 × 4): |Δt| + 2·sin(θ/2)·radius, θ the angle between the rotations."""
    return float(moves_by(before[None], after[None], np.array([radius]))[0])


def moves_by(before: FloatArray, after: FloatArray, radii: FloatArray) -> FloatArray:
    """`moved_by` of many bodies at once: poses (B, 4, 4) before and after, radii (B,).
    With cos θ = (tr(R'Rᵀ) − 1)/2, 2·sin(θ/2) = √(2 − 2·cos θ); tr(R'Rᵀ) = Σ R' ∘ R."""
    trace = np.einsum("bij,bij->b", after[:, :3, :3], before[:, :3, :3])
    cos = np.clip((trace - 1.0) / 2.0, -1.0, 1.0)
    chord = np.sqrt(np.maximum(2.0 - 2.0 * cos, 0.0))
    return np.asarray(np.linalg.norm(after[:, :3, 3] - before[:, :3, 3], axis=1) + chord * radii)


@dataclass(frozen=True)
class ObjectClearance:
    """What a certificate proved about the object of an id: the path's interior stayed at least
    `clearance` from it, as it was: `shape` (`shape_digest`) at `pose` (4 × 4)."""

    shape: str
    pose: FloatArray
    clearance: float

    def holds_for(self, obj: SceneObject, shape: str) -> bool:
        """Whether it proves the interior clear of `obj` (module docstring)."""
        if shape != self.shape:
            return False
        shift = float(np.linalg.norm(obj.pose[:3, 3] - self.pose[:3, 3]))
        if shift >= self.clearance:  # the move's bound is at least this: no need for the turn
            return False
        return moved_by(self.pose, obj.pose, obj.shape.bounding_radius()) < self.clearance


def object_digests(scene: Scene) -> dict[str, str]:
    """Each world object's digest, by id (an object id in an allowed pair covers its parts);
    kept per scene content hash."""
    return _digests(scene, pose=True)


def shape_digests(scene: Scene) -> dict[str, str]:
    """Each world object's `shape_digest`, by id; kept per scene content hash."""
    return _digests(scene, pose=False)


def _digests(scene: Scene, *, pose: bool) -> dict[str, str]:
    known = _SCENE_DIGESTS.get((scene.hash, pose)) if scene.hash else None
    if known is not None:
        return known
    touches = _touches(scene)
    shapes = {
        obj.id: shape_digest(obj, touches.get(obj.id.partition("#")[0], ()))
        for obj in scene.objects
    }
    posed = {obj.id: _posed(shapes[obj.id], obj) for obj in scene.objects}
    if scene.hash:  # both at once: a scene's first certificate use asks for both
        _SCENE_DIGESTS.put((scene.hash, False), shapes)
        _SCENE_DIGESTS.put((scene.hash, True), posed)
    return posed if pose else shapes


def _touches(scene: Scene) -> dict[str, list[str]]:
    touches: dict[str, list[str]] = {}
    for a, b in scene.allowed:
        touches.setdefault(a, []).append(b)
        touches.setdefault(b, []).append(a)
    return touches


def merged(known: frozenset[str], scene: Mapping[str, str]) -> frozenset[str]:
    """A certificate's digests after a valid verdict in a scene: the scene's, then as many of
    those it already held as `MAX_OBJECTS` leaves room for."""
    current = set(scene.values())
    room = max(MAX_OBJECTS - len(current), 0)
    return frozenset(current | set(sorted(known - current)[:room]))


@dataclass(frozen=True)
class Held:
    """What a certificate holds, as a validation uses it: the object digests it was certified
    for, its clearances by object id, and the test of its swept envelope."""

    objects: frozenset[str]
    clearances: Mapping[str, ObjectClearance] | None = None
    clear_of: Callable[[SceneObject], bool] | None = None


def validate_with_certificate(
    states: FloatArray,
    *,
    full: TrajectoryValidator,
    scene_only: Callable[[list[SceneObject]], TrajectoryValidator],
    scene: Scene,
    held: Held,
    audit: bool = False,
    ends_fn: Callable[[FloatArray, list[int]], ValidationResult] | None = None,
) -> tuple[ValidationResult, CertificateUse]:
    """Validate an adapted path (n ≥ 4) whose interior holds a certificate (`held`): its first
    and last segments with `ends_fn` (default `full`'s `validate_segments`), its interior
    against the objects the certificate lacks with `scene_only(objects)`, except those that
    moved within its clearances and those clear of its swept envelope (module docstring)."""
    digests = object_digests(scene)
    new = [obj for obj in scene.objects if digests[obj.id] not in held.objects]
    moved, clearances, clear_fn = 0, held.clearances, held.clear_of
    if clearances and new:
        shapes = shape_digests(scene)
        within = {
            o.id for o in new if o.id in clearances and clearances[o.id].holds_for(o, shapes[o.id])
        }
        moved = len(within)
        new = [o for o in new if o.id not in within]
    clear = 0
    if clear_fn is not None and new:
        remaining = [o for o in new if not clear_fn(o)]
        clear, new = len(new) - len(remaining), remaining
    use = CertificateUse(len(scene.objects), len(new), moved, clear)
    result = (ends_fn or full.validate_segments)(states, [0, len(states) - 2])
    if result.valid and new:
        inner = scene_only(new).validate(states[1:-1])
        inner.samples += result.samples
        inner.narrow_checks += result.narrow_checks
        inner.subdivisions += result.subdivisions
        inner.elapsed_ms += result.elapsed_ms
        result = inner
    if audit and result.valid:
        truth = full.validate(states)
        if not truth.valid:
            raise CertificateDisagreement(
                f"a certificate passed a path that full validation finds {truth.status.value}: "
                f"{truth.message}"
            )
    return result, use
