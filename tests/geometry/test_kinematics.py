"""Forward kinematics against yourdfpy, state checks and the link motion bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from yourdfpy import URDF

from tests.robots import ARM_PATH, ARM_URDF, OFFSET_BALL_URDF, TURN_AND_SLIDE_URDF
from trajcache.geometry.errors import StateError
from trajcache.geometry.model.kinematics import (
    check_limits,
    check_states,
    element_transforms,
    link_motion_bounds,
    link_transforms,
)
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model


def _random_states(model: RobotModel, n: int, rng: np.random.Generator) -> FloatArray:
    lower = np.where(np.isfinite(model.lower), model.lower, -2.0)
    upper = np.where(np.isfinite(model.upper), model.upper, 2.0)
    return rng.uniform(lower, upper, size=(n, model.dof))


def test_fk_matches_yourdfpy() -> None:
    model = load_robot_model(ARM_URDF)
    reference = URDF.load(str(ARM_PATH), build_scene_graph=True, load_meshes=False)
    states = _random_states(model, 60, np.random.default_rng(1))
    tf = link_transforms(model, states)
    assert tf.shape == (60, len(model.link_names), 4, 4)
    for state, poses in zip(states, tf, strict=True):
        reference.update_cfg({n: float(v) for n, v in zip(model.joint_names, state, strict=True)})
        for link, name in enumerate(model.link_names):
            expected = reference.get_transform(name, model.link_names[0])
            np.testing.assert_allclose(poses[link], expected, atol=1e-9)


def test_fk_holds_non_planning_joints_at_their_default() -> None:
    model = load_robot_model(ARM_URDF, joint_names=["j1", "j2"])
    reference = URDF.load(str(ARM_PATH), build_scene_graph=True, load_meshes=False)
    reference.update_cfg({"j1": 0.4, "j2": -1.0, "j4": 0.0, "slide": 0.0, "flag_joint": 0.2})
    tf = link_transforms(model, [0.4, -1.0])
    assert tf.shape == (1, len(model.link_names), 4, 4)
    flag = model.link_names.index("flag")
    np.testing.assert_allclose(tf[0, flag], reference.get_transform("flag", "base_link"), atol=1e-9)


def test_planar_base_fk_by_hand() -> None:
    model = load_robot_model(OFFSET_BALL_URDF, base="planar")
    x, y, theta, q = 1.0, 2.0, math.pi / 2, math.pi / 4
    tf = link_transforms(model, np.array([x, y, theta, q]))[0]
    c, s = math.cos(theta + q), math.sin(theta + q)
    expected = np.array([[c, -s, 0, 1.0], [s, c, 0, 2.5], [0, 0, 1, 0.3], [0, 0, 0, 1]])
    np.testing.assert_allclose(tf[1], expected, atol=1e-12)
    base = np.array([[0, -1, 0, 1.0], [1, 0, 0, 2.0], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_allclose(tf[0], base, atol=1e-12)


def test_element_transforms_compose_link_and_origin() -> None:
    model = load_robot_model(ARM_URDF, base="planar")
    states = _random_states(model, 5, np.random.default_rng(2))
    links = link_transforms(model, states)
    elements = element_transforms(model, links)
    assert elements.shape == (5, len(model.elements), 4, 4)
    for e, element in enumerate(model.elements):
        np.testing.assert_allclose(elements[:, e], links[:, element.link] @ element.origin)


def test_check_states_names_the_problem() -> None:
    model = load_robot_model(ARM_URDF, base="planar")
    with pytest.raises(StateError, match=r"start has 7 values, expected 8 \(base_x, base_y"):
        check_states(model, np.zeros(7), name="start")
    with pytest.raises(StateError, match="each state has 9 values"):
        check_states(model, np.zeros((3, 9)))
    bad = np.zeros(8)
    bad[4] = np.nan
    with pytest.raises(StateError, match=r"goal value 4 \(j1\) is not finite"):
        check_states(model, bad, name="goal")
    with pytest.raises(StateError, match="numbers"):
        check_states(model, ["a"] * 8)
    ragged = [[0.0] * 8, [0.0] * 8, [0.0] * 3]
    with pytest.raises(StateError, match=r"^waypoint 2 has 3 values, expected 8 \(base_x") as err:
        check_states(model, ragged, name="waypoint")
    assert "inhomogeneous" not in str(err.value)  # numpy's own words are not the message
    assert check_states(model, np.zeros(8)).shape == (1, 8)


def test_check_limits_names_joints_and_wraps_theta() -> None:
    model = load_robot_model(ARM_URDF, base="planar")
    ok = np.array([100.0, -50.0, 12.0, 0.0, 0.0, 0.0, 0.0, 0.5])
    check_limits(model, ok)
    bad = ok.copy()
    bad[4], bad[6] = 2.7, 0.25
    with pytest.raises(StateError, match=r"j1 = 2.7 not in \[-2.5, 2.5\]; slide = 0.25"):
        check_limits(model, bad, name="start")
    with pytest.raises(StateError, match="state 1"):
        check_limits(model, np.stack([ok, bad]))


def _local_points(model: RobotModel) -> list[FloatArray]:
    """Sample points of every element in its own frame: centre, corners, rims, vertices."""
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    points = []
    for element in model.elements:
        shape = element.shape
        if shape.kind is ShapeKind.BOX:
            pts = signs * shape.half_extents()
        elif shape.kind is ShapeKind.SPHERE:
            pts = np.vstack([np.eye(3), -np.eye(3), signs / math.sqrt(3)]) * shape.size[0]
        elif shape.kind is ShapeKind.CYLINDER:
            angles = np.linspace(0, 2 * math.pi, 12, endpoint=False)
            rim = np.stack([np.cos(angles), np.sin(angles), np.zeros(12)], axis=1) * shape.size[0]
            cap = np.array([0.0, 0.0, shape.size[1] / 2])
            pts = np.vstack([rim + cap, rim - cap])
        else:
            assert shape.vertices is not None
            pts = shape.vertices
        points.append(np.vstack([np.zeros(3), pts]))
    return points


@pytest.mark.parametrize("base", ["fixed", "planar"])
def test_link_motion_bounds_hold_empirically(base: str) -> None:
    model = load_robot_model(ARM_URDF, base=base)
    bounds = link_motion_bounds(model)
    assert bounds.shape == (len(model.link_names), model.dof)
    assert not bounds[model.link_names.index("camera_link")].any()  # no geometry
    rng = np.random.default_rng(7)
    a = _random_states(model, 200, rng)
    b = _random_states(model, 200, rng)
    t = np.linspace(0.0, 1.0, 50)
    path = a[:, None] + t[None, :, None] * (b - a)[:, None]  # (200, 50, D)
    poses = element_transforms(model, link_transforms(model, path.reshape(-1, model.dof)))
    poses = poses.reshape(200, 50, len(model.elements), 4, 4)
    allowed = np.abs(b - a) @ bounds.T  # (200, L)
    tightest = 0.0
    for e, local in enumerate(_local_points(model)):
        world = poses[:, :, e, :3, :3] @ local.T + poses[:, :, e, :3, 3:]  # (200, 50, 3, P)
        moved = np.linalg.norm(world - world[:, :1], axis=2).max(axis=(1, 2))
        limit = allowed[:, model.elements[e].link]
        assert np.all(moved <= limit + 1e-9), f"element {e} moved {moved.max()} > bound"
        moving = limit > 0
        tightest = max(tightest, float(np.max(moved[moving] / limit[moving], initial=0.0)))
    assert tightest > 0.3  # the bound is not vacuous


def test_link_motion_bounds_only_count_ancestors() -> None:
    model = load_robot_model(ARM_URDF)
    bounds = link_motion_bounds(model)
    flag = model.link_names.index("flag")
    tool = model.link_names.index("tool")
    slide = model.joint_names.index("slide")
    assert np.count_nonzero(bounds[flag]) == 1  # only flag_joint moves it
    assert bounds[tool, slide] == 1.0  # prismatic ancestor
    assert bounds[model.link_names.index("link1"), slide] == 0.0  # descendant joint


@pytest.mark.parametrize("moving", [2, 3, 4])
def test_link_motion_bounds_are_tight_at_full_extension(moving: int) -> None:
    model = load_robot_model(TURN_AND_SLIDE_URDF, base="planar")
    bounds = link_motion_bounds(model)
    np.testing.assert_allclose(bounds[2], [1.0, 1.0, 0.9, 0.9, 1.0])
    start = np.array([0.0, 0.0, 0.0, 0.2, 0.5])
    end = start.copy()
    end[moving] -= 1e-3
    path = start + np.linspace(0, 1, 20)[:, None] * (end - start)
    poses = element_transforms(model, link_transforms(model, path))[:, 0]
    local = _local_points(model)[0]
    world = poses[:, :3, :3] @ local.T + poses[:, :3, 3:]
    moved = np.linalg.norm(world - world[:1], axis=1).max()
    ratio = moved / (bounds[2] @ np.abs(end - start))
    assert 0.999 < ratio <= 1.0 + 1e-9
