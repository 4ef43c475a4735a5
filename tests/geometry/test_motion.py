"""Motion bounds along straight segments: they hold, for pairs too, and they are not vacuous."""

from __future__ import annotations

import numpy as np
import pytest

from tests.robots import ARM_URDF  # has a prismatic joint
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.motion import MotionBounds, motion_bounds
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.robot import reference_model


def _states(model: RobotModel, n: int, rng: np.random.Generator) -> FloatArray:
    lower = np.where(np.isfinite(model.lower), model.lower, -2.0)
    upper = np.where(np.isfinite(model.upper), model.upper, 2.0)
    return rng.uniform(lower, upper, size=(n, model.dof))


def _segments(model: RobotModel, rng: np.random.Generator, n: int) -> tuple[FloatArray, FloatArray]:
    """Segment ends: short (sample-sized), medium and long steps, some dofs still."""
    a = _states(model, n, rng)
    scale = rng.choice([0.035, 0.3, 1.5], size=(n, 1))
    b = a + rng.normal(0.0, 1.0, size=a.shape) * scale * (rng.random(a.shape) < 0.7)
    b = np.clip(b, np.where(np.isfinite(model.lower), model.lower, -3.0), model.upper)
    return a, b


def _paths(
    model: RobotModel, a: FloatArray, b: FloatArray, links: FloatArray, local: FloatArray
) -> FloatArray:
    """World positions (S, T, P, 3) of points `local` (P, 3) on `links` (P,) along each segment."""
    t = np.linspace(0.0, 1.0, 400)
    states = a[:, None] + t[None, :, None] * (b - a)[:, None]
    tf = link_transforms(model, states.reshape(-1, model.dof)).reshape(len(a), len(t), -1, 4, 4)
    frames = tf[:, :, links]
    return np.einsum("stpij,pj->stpi", frames[..., :3, :3], local) + frames[..., :3, 3]


def _path_length(points: FloatArray) -> FloatArray:
    return np.asarray(np.linalg.norm(np.diff(points, axis=1), axis=-1).sum(axis=1))


def _levers(
    bounds: MotionBounds,
    model: RobotModel,
    a: FloatArray,
    b: FloatArray,
    at: FloatArray,
    links: FloatArray,
    local: FloatArray,
) -> FloatArray:
    """Per (segment, point, dof) levers from the path ends `at` (S, T, P, 3)."""
    tf_a, tf_b = link_transforms(model, a), link_transforms(model, b)
    axes_a, axes_b = bounds.axes(tf_a), bounds.axes(tf_b)
    r_a = bounds.axis_distances(at[:, 0], (axes_a[0][:, None], axes_a[1][:, None]))
    r_b = bounds.axis_distances(at[:, -1], (axes_b[0][:, None], axes_b[1][:, None]))
    coef = bounds.coefficients(links, np.linalg.norm(local, axis=1))
    return bounds.levers(r_a, r_b, coef, bounds.steps(b - a)[:, None])


@pytest.mark.parametrize("base", ["fixed", "planar"])
def test_no_point_moves_farther_than_its_bound(base: str) -> None:
    model = load_robot_model(ARM_URDF, base=base)
    bounds = motion_bounds(model)
    rng = np.random.default_rng(3)
    a, b = _segments(model, rng, 60)
    links = rng.integers(0, len(model.link_names), size=12)
    local = rng.normal(0.0, 0.15, size=(12, 3))
    at = _paths(model, a, b, links, local)
    bound = _levers(bounds, model, a, b, at, links, local).sum(axis=-1)  # (S, P)
    moved = _path_length(at)
    assert np.all(moved <= bound + 1e-9), float(np.max(moved - bound))
    moving = bound > 1e-6
    assert np.max(moved[moving] / bound[moving]) > 0.8  # tight somewhere, not vacuous
    # Never looser than the configuration-independent coefficients alone.
    coef = bounds.coefficients(links, np.linalg.norm(local, axis=1))
    assert np.all(bound <= bounds.steps(b - a) @ coef.T + 1e-9)


def test_the_bound_follows_the_configuration() -> None:
    # Folded, the reference arm's tool is much nearer joint 1's axis than its reach allows.
    model = reference_model()
    bounds = motion_bounds(model)
    folded = np.array([0.0, 0.0, 0.0, 0.0, -1.3, 0.0, 0.8, 0.0, 2.1, 0.0])
    turned = folded.copy()
    turned[3] += 0.035  # joint 1
    tool = np.array([model.link_names.index("tool")])
    tip = np.array([[0.0, 0.0, 0.15]])
    at = _paths(model, folded[None], turned[None], tool, tip)
    lever = _levers(bounds, model, folded[None], turned[None], at, tool, tip)[0, 0]
    reach = bounds.coefficients(tool, np.linalg.norm(tip, axis=1))[0]
    assert lever[3] < 0.4 * 0.035 * reach[3]
    assert lever[3] >= _path_length(at)[0, 0] - 1e-12


def test_pairs_only_count_the_dofs_between_them() -> None:
    model = reference_model()
    bounds = motion_bounds(model)
    rng = np.random.default_rng(11)
    a, b = _segments(model, rng, 40)
    link4, tool = model.link_names.index("link4"), model.link_names.index("tool")
    links = np.array([link4, tool])
    local = np.array([[0.05, -0.1, 0.0], [0.0, 0.0, 0.15]])
    at = _paths(model, a, b, links, local)
    levers = _levers(bounds, model, a, b, at, links, local)  # (S, 2, D)
    mask = ~(bounds.ancestors[link4] & bounds.ancestors[tool])
    assert not mask[:7].any() and mask[7:].all()  # base and joints 1–4 move both alike
    bound = (levers * mask).sum(axis=(1, 2))
    # The way between the points, seen from link4, moves no farther than that (and so neither
    # does their distance, nor the distance between any bodies carried by the two links).
    t = np.linspace(0.0, 1.0, at.shape[1])
    states = a[:, None] + t[None, :, None] * (b - a)[:, None]
    frames = link_transforms(model, states.reshape(-1, model.dof))[:, link4]
    frames = frames.reshape(len(a), len(t), 4, 4)
    gap = np.einsum("stji,stj->sti", frames[..., :3, :3], at[:, :, 1] - at[:, :, 0])
    moved = np.linalg.norm(np.diff(gap, axis=1), axis=-1).sum(axis=1)
    assert np.all(moved <= bound + 1e-9)
    assert np.max(moved / np.maximum(bound, 1e-12)) > 0.5
    assert np.all(bound <= levers.sum(axis=(1, 2)) + 1e-12)


def test_a_ball_around_a_point_moves_at_most_lever_plus_radius_times_turn() -> None:
    model = load_robot_model(ARM_URDF, base="planar")
    bounds = motion_bounds(model)
    rng = np.random.default_rng(5)
    a, b = _segments(model, rng, 40)
    link = np.array([model.link_names.index("tool")])
    centre = np.array([[0.02, 0.0, 0.1]])
    radius = 0.07
    offsets = rng.normal(size=(30, 3))
    offsets *= radius * rng.random((30, 1)) ** (1 / 3) / np.linalg.norm(offsets, axis=1)[:, None]
    at = _paths(model, a, b, np.repeat(link, 31), np.vstack([centre, centre + offsets]))
    centre_bound = _levers(bounds, model, a, b, at[:, :, :1], link, centre).sum(axis=(1, 2))
    turn = bounds.turn(link, bounds.steps(b - a)).sum(axis=-1)
    moved = _path_length(at).max(axis=1)
    assert np.all(moved <= centre_bound + radius * turn + 1e-9)
