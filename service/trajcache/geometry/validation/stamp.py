"""Certificates: the digest that lets one process take another's certified verdict.

A planner worker certifies the path it returns with the same validator the service would run
on it (`planning/attempts.plan_until_certified` returns SOLVED only for paths its validator
certified, whole or segment by segment, which is the same verdict: validation certifies each
straight segment on its own, `cache/memo.py`). The service would then validate that path a
second time. It need not, when it can tell that its own validation is the same computation on
the same inputs, because validation is deterministic:

- the same code: the certifier digest is SHA-256 of the source of every module of
  `trajcache.geometry` (models, kinematics, collision, scenes, validation), where every verdict
  is decided. A worker of another release, or with one changed line there, has another digest;
- the same robot: the model variant's id, the content hash of the robot with its held joints,
  attached objects and allowed pairs (`scene/variant.py`);
- the same scene: its content hash;
- the same settings: the validator's `settings_key` (resolution, certified mode, padding, depth);
- the same states: the exact float64 bytes of the key states.

`certificate_digest` hashes all five. The worker's validator issues it for the path it
certified (`TrajectoryValidator.certificate`); the service computes it with its own validator
for the path it received, and skips its validation only when both are equal. Anything that
differs (a worker of another version, another variant, a path changed after certification, a
certificate from anywhere else) gives another digest, and the path is validated as any other.
A certificate is never read from a client: only the planner pool's results carry one.
"""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

import numpy as np

from trajcache.geometry.model.shapes import FloatArray

_GEOMETRY = Path(__file__).resolve().parents[1]  # trajcache/geometry


@cache
def certifier_digest() -> str:
    """SHA-256 of the source of every module under `trajcache.geometry`, by relative path."""
    digest = hashlib.sha256()
    for path in sorted(_GEOMETRY.rglob("*.py")):
        digest.update(path.relative_to(_GEOMETRY).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def certificate_digest(
    model_id: str, scene_hash: str, settings: tuple[object, ...], key_states: FloatArray
) -> str:
    """The certificate of a valid verdict (module docstring); "" for a scene without a content
    hash, which no certificate can name."""
    if not scene_hash:
        return ""
    digest = hashlib.sha256()
    for part in (certifier_digest(), model_id, scene_hash, repr(settings)):
        digest.update(part.encode())
        digest.update(b"\0")
    states = np.ascontiguousarray(np.asarray(key_states, dtype=np.float64))
    digest.update(repr(states.shape).encode())
    digest.update(states.tobytes())
    return digest.hexdigest()
