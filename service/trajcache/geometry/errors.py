"""Domain errors of the geometry layer; the API maps every one of them to a 422.

GeometryError
├── RobotModelError       malformed URDF, unknown joints, bad base type
│   ├── MeshError         missing or unreadable mesh file
│   └── UnsafePathError   a mesh URI or archive entry escapes the uploaded files
├── SceneError            malformed scene, non-finite pose, bad quaternion, bad shape size
└── StateError            wrong state length, NaN/Inf, out of limits
"""

from __future__ import annotations

from collections.abc import Sequence


class GeometryError(ValueError):
    """Base class: the input describes geometry that cannot be used."""


class RobotModelError(GeometryError):
    """The robot description (URDF, joints, base type) is unusable."""


class MeshError(RobotModelError):
    """A mesh file referenced by the URDF is missing or unreadable."""


class UnsafePathError(RobotModelError):
    """A mesh URI or archive entry points outside the uploaded files."""


class SceneError(GeometryError):
    """The scene description is malformed."""


class StateError(GeometryError):
    """A robot state has the wrong length, a non-finite value or is out of limits."""


class CollisionStateError(StateError):
    """A start or goal state collides; `contacts` names the links and objects involved."""

    def __init__(self, message: str, *, contacts: Sequence[object] = ()) -> None:
        super().__init__(message)
        self.contacts = list(contacts)
