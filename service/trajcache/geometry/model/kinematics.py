"""Batched forward kinematics, state checks and motion bounds of a `RobotModel`."""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from trajcache.core.suggest import unknown_message
from trajcache.geometry.errors import StateError
from trajcache.geometry.model.kernels import forward_kinematics_kernel
from trajcache.geometry.model.robot import BaseType, KinematicJoint, RobotModel
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]

_LIMIT_TOL = 1e-9


@dataclass(frozen=True)
class _Tables:
    """Per-model arrays precomputed once for the hot paths.

    Every joint's parent → child transform at value q is `fixed + sin(q)·sine +
    (1 − cos(q))·versine + q·slide` (Rodrigues' formula folded into the joint origin; `slide`
    moves a prismatic joint along its axis), so one expression gives all joints at once.
    """

    element_link: IntArray  # (E,)
    element_origin: FloatArray  # (E, 4, 4)
    value_index: IntArray  # (J,) state column of each joint, or -1 when held at its default
    value_scale: FloatArray  # (J,) a mimic joint's multiplier of that column (else 1)
    value_offset: FloatArray  # (J,) and its offset (else 0)
    default: FloatArray  # (J,) value of held joints
    fixed: FloatArray  # (J, 4, 4)
    sine: FloatArray  # (J, 4, 4)
    versine: FloatArray  # (J, 4, 4)
    slide: FloatArray  # (J, 4, 4)
    parent: IntArray  # (J,) parent link of each joint
    child: IntArray  # (J,) child link


_TABLES: weakref.WeakKeyDictionary[RobotModel, _Tables] = weakref.WeakKeyDictionary()
_BOUNDS: weakref.WeakKeyDictionary[RobotModel, tuple[FloatArray, FloatArray]] = (
    weakref.WeakKeyDictionary()
)


def _tables(model: RobotModel) -> _Tables:
    tables = _TABLES.get(model)
    if tables is None:
        count = len(model.joints)
        fixed = np.array([j.origin for j in model.joints], dtype=float).reshape(count, 4, 4)
        sine, versine, slide = (np.zeros((count, 4, 4)) for _ in range(3))
        for k, joint in enumerate(model.joints):
            rot = joint.origin[:3, :3]
            if joint.kind in ("revolute", "continuous"):
                x, y, z = joint.axis
                cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
                sine[k, :3, :3] = rot @ cross
                versine[k, :3, :3] = rot @ cross @ cross
            elif joint.kind == "prismatic":
                slide[k, :3, 3] = rot @ joint.axis
        tables = _Tables(
            element_link=np.array([e.link for e in model.elements], dtype=np.int64),
            element_origin=np.array([e.origin for e in model.elements], dtype=float).reshape(
                -1, 4, 4
            ),
            value_index=np.array([j.index for j in model.joints], dtype=np.int64),
            value_scale=np.array([j.scale for j in model.joints], dtype=float),
            value_offset=np.array([j.offset for j in model.joints], dtype=float),
            default=np.array([j.default for j in model.joints], dtype=float),
            fixed=fixed,
            sine=sine,
            versine=versine,
            slide=slide,
            parent=np.array([j.parent for j in model.joints], dtype=np.int64),
            child=np.array([j.child for j in model.joints], dtype=np.int64),
        )
        _TABLES[model] = tables
    return tables


def check_states(model: RobotModel, states: ArrayLike, *, name: str = "state") -> FloatArray:
    """Return `states` as an (N, D) float array; raise StateError on a wrong length or NaN/Inf."""
    names = model.state_names
    try:
        arr = np.asarray(states, dtype=float)
    except (TypeError, ValueError):
        raise StateError(_ragged_message(states, name, model.dof, _expected(model))) from None
    if arr.ndim == 1:
        if arr.shape[0] != model.dof:
            raise StateError(f"{name} has {arr.shape[0]} values, {_expected(model)}")
        arr = arr[None, :]
    elif arr.ndim != 2 or arr.shape[1] != model.dof:
        got = arr.shape[-1] if arr.ndim >= 1 else 0
        raise StateError(f"each {name} has {got} values, {_expected(model)}")
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))
        row, col = (int(v) for v in bad[0])
        where = name if arr.shape[0] == 1 else f"{name} {row}"
        raise StateError(f"{where} value {col} ({names[col]}) is not finite: {arr[row, col]}")
    return arr


def _expected(model: RobotModel) -> str:
    return f"expected {model.dof} ({', '.join(model.state_names)})"


def _ragged_message(states: object, name: str, dof: int, expected: str) -> str:
    """Why `states` is not an (N, D) array of numbers: the first row of another length, or
    that it holds something other than numbers."""
    if isinstance(states, (list, tuple)):
        for row, values in enumerate(states):
            if isinstance(values, (list, tuple)) and len(values) != dof:
                return f"{name} {row} has {len(values)} values, {expected}"
    return f"{name} must be a list of numbers, or a list of such lists ({expected})"


HELD_TOLERANCE = 1e-6  # how far a held joint's value in a named-joint state may be off


StateInput = ArrayLike | Mapping[str, float] | str


def resolve_state(model: RobotModel, value: StateInput, *, name: str = "state") -> ArrayLike:
    """A state given as values in `state_names` order, as a {joint name: value} map, or as the
    name of one of the model's named states (SRDF group states), as values in order.

    A map needs every state name; it may also give joints held outside the planning joints,
    whose values must then be the held ones. StateError names what does not fit.
    """
    if isinstance(value, str):
        if value not in model.named_states:
            known = sorted(model.named_states)
            raise StateError(f"{name}: {unknown_message('named state', [value], known)}")
        if model.arm_offset:
            raise StateError(
                f"{name}: a named state gives the planning joints only; a planar base needs "
                f"base_x, base_y and base_theta too: send a map of {', '.join(model.state_names)}"
            )
        return list(model.named_states[value])
    if not isinstance(value, Mapping):
        return value
    names = model.state_names
    if unknown := [j for j in value if j not in names and j not in model.held_values]:
        valid = [*names, *model.held_values]
        raise StateError(
            f"{name}: {unknown_message('joint', unknown, valid, list_valid=False)}"
            f" (expected {', '.join(names)})"
        )
    if missing := [n for n in names if n not in value]:
        raise StateError(f"{name} lacks {', '.join(missing)} (expected {', '.join(names)})")
    for joint, given in value.items():
        if joint in names:
            continue
        held = model.held_values[joint]
        if not abs(float(given) - held) <= HELD_TOLERANCE:
            raise StateError(
                f"{name}: {joint} = {float(given):.6g}, but the model holds it at {held:.6g} "
                "(held joints are set at registration)"
            )
    return [value[n] for n in names]


def check_limits(model: RobotModel, states: ArrayLike, *, name: str = "state") -> None:
    """Raise StateError naming every joint of the first offending state that is out of limits.

    The base θ is wrapped (never out of limits) and the base x/y are unbounded.
    """
    arr = check_states(model, states, name=name)
    lower, upper = _bounds(model)
    out = (arr < lower - _LIMIT_TOL) | (arr > upper + _LIMIT_TOL)
    if not out.any():
        return
    rows = np.flatnonzero(out.any(axis=1))
    row = int(rows[0])
    names = model.state_names
    parts = [
        f"{names[d]} = {arr[row, d]:.6g} not in [{lower[d]:.6g}, {upper[d]:.6g}]"
        for d in np.flatnonzero(out[row])
    ]
    where = name if arr.shape[0] == 1 else f"{name} {row} (of {len(rows)} out of limits)"
    raise StateError(f"{where} is out of joint limits: {'; '.join(parts)}")


def _bounds(model: RobotModel) -> tuple[FloatArray, FloatArray]:
    """The limits `check_limits` applies (a planar base's pose unbounded), read-only, kept per
    model: every request checks its start and goal against them."""
    bounds = _BOUNDS.get(model)
    if bounds is None:
        lower, upper = model.lower.copy(), model.upper.copy()
        if model.base is BaseType.PLANAR:
            lower[:3], upper[:3] = -np.inf, np.inf
        lower.flags.writeable = upper.flags.writeable = False
        bounds = _BOUNDS[model] = (lower, upper)
    return bounds


def link_transforms(model: RobotModel, states: ArrayLike) -> FloatArray:
    """World pose of every link for every state, shape (N, L, 4, 4); a (D,) state gives N = 1."""
    return forward_kinematics(model, check_states(model, states))


def forward_kinematics(model: RobotModel, q: FloatArray) -> FloatArray:
    """`link_transforms` of states already checked: a finite (N, D) float array (compiled)."""
    tf = np.empty((q.shape[0], len(model.link_names), 4, 4))
    forward_kinematics_kernel(np.ascontiguousarray(q, dtype=float), *fk_tables(model), tf)
    return tf


def fk_tables(model: RobotModel) -> tuple[object, ...]:
    """`forward_kinematics_kernel`'s arguments between the states and the output, for kernels
    that pose states themselves."""
    tables = _tables(model)
    return (
        model.base is BaseType.PLANAR,
        tables.parent,
        tables.child,
        tables.value_index,
        tables.value_scale,
        tables.value_offset,
        tables.default,
        tables.fixed,
        tables.sine,
        tables.versine,
        tables.slide,
    )


def element_transforms(model: RobotModel, link_tf: FloatArray) -> FloatArray:
    """World pose of every collision element, shape (N, E, 4, 4), from `link_transforms`."""
    tables = _tables(model)
    result: FloatArray = link_tf[:, tables.element_link] @ tables.element_origin[None]
    return result


def link_motion_bounds(model: RobotModel) -> FloatArray:
    """Configuration-independent per-link motion coefficients c (L, D) for straight segments.

    Claim: for any states a, b within limits and every t ∈ [0, 1], every point p of link l's
    collision geometry moves at most Σ_d c[l, d] · |b_d − a_d| along s(t) = a + t (b − a).

    Derivation: along the segment the state velocity is constant, ṡ = b − a. A point of link l
    moves with velocity  v_p = v_base + ω_base × (p − o_root) + Σ_j q̇_j · (u_j × (p − o_j))
    (revolute ancestors j, unit axis u_j through o_j) + Σ_k q̇_k · u_k (prismatic ancestors k), so
    |v_p| ≤ |ẋ| + |ẏ| + |θ̇| · dist(p, vertical axis through o_root)
            + Σ_j |q̇_j| · dist(p, axis_j) + Σ_k |q̇_k|.
    Every distance is bounded independently of the configuration by the triangle inequality over
    the kinematic chain: dist(p, axis_j) ≤ |p − o_j| ≤ R_jl = Σ_{joints i strictly after j on the
    chain to l} (|origin translation of i| + max |q_i| over the limits if i is prismatic)
    + max over l's elements (|element origin translation| + shape bounding radius).
    The base θ uses the same sum over the whole chain from the root. Integrating |v_p| over
    t ∈ [0, 1] gives the claim with c = 1 for x and y, R_root,l for θ, R_jl for revolute and
    continuous ancestors, 1 for prismatic ancestors and 0 for every other joint. Links without
    geometry get zeros.
    """
    n_links = len(model.link_names)
    bounds = np.zeros((n_links, model.dof))
    geometry = np.zeros(n_links)
    has_geometry = np.zeros(n_links, dtype=bool)
    for e in model.elements:
        radius = float(np.linalg.norm(e.origin[:3, 3])) + e.shape.bounding_radius()
        geometry[e.link] = max(geometry[e.link], radius)
        has_geometry[e.link] = True
    parent_joint = {joint.child: joint for joint in model.joints}
    for link in np.flatnonzero(has_geometry):
        reach = float(geometry[link])  # bound on |p − o| for o the frame of the current joint
        current = int(link)
        while current in parent_joint:
            joint = parent_joint[current]
            if joint.index >= 0:
                lever = abs(joint.scale) if joint.kind == "prismatic" else reach
                bounds[link, joint.index] += lever
            reach += float(np.linalg.norm(joint.origin[:3, 3])) + prismatic_extent(model, joint)
            current = joint.parent
        if model.base is BaseType.PLANAR:
            bounds[link, :3] = (1.0, 1.0, reach)
    return bounds


def prismatic_extent(model: RobotModel, joint: KinematicJoint) -> float:
    """Largest |value| a prismatic joint can take within the limits (0 for other joints)."""
    if joint.kind != "prismatic":
        return 0.0
    if joint.index < 0:
        return abs(joint.default)
    ends = (model.lower[joint.index], model.upper[joint.index])
    return float(max(abs(joint.scale * end + joint.offset) for end in ends))
