"""The reference robot (URDF facts, geometry, stowed pose) and the restroom scene.

Forward kinematics here uses yourdfpy and collisions use python-fcl directly, independent of the
project's own kinematics and collision modules.
"""

from __future__ import annotations

import io
import itertools
import math

import fcl
import numpy as np
import pytest
import yourdfpy

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.scene.moveit import scene_to_moveit
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.restroom import (
    RESTROOM_LAYOUT,
    STALL_FRONTS,
    restroom_layout,
    restroom_scene,
)
from trajcache.reference.robot import (
    ARM_JOINT_NAMES,
    BASE_SIZE,
    STOWED_ARM,
    reference_model,
    reference_urdf,
)

HALF_PI = math.pi / 2
JOINT_TABLE = [  # REFERENCE.md: xyz, rpy, lower, upper
    ((0, 0, 0.267), (0, 0, 0), -6.283185307, 6.283185307),
    ((0, 0, 0), (-HALF_PI, 0, 0), -2.059, 2.0944),
    ((0, -0.293, 0), (HALF_PI, 0, 0), -6.283185307, 6.283185307),
    ((0.0525, 0, 0), (HALF_PI, 0, 0), -0.19198, 3.927),
    ((0.0775, -0.3425, 0), (HALF_PI, 0, 0), -6.283185307, 6.283185307),
    ((0, 0, 0), (HALF_PI, 0, 0), -1.69297, math.pi),
    ((0.076, 0.097, 0), (-HALF_PI, 0, 0), -6.283185307, 6.283185307),
]
LINK_BOXES = {  # REFERENCE.md link-frame bounding boxes: (min xyz, max xyz)
    "link1": ((-0.049, -0.057, -0.112), (0.048, 0.075, 0.048)),
    "link2": ((-0.048, -0.192, -0.042), (0.047, 0.047, 0.119)),
    "link3": ((-0.042, -0.067, -0.101), (0.095, 0.069, 0.043)),
    "link4": ((-0.043, -0.169, -0.043), (0.120, 0.043, 0.107)),
    "link5": ((-0.042, -0.043, -0.173), (0.042, 0.086, 0.038)),
    "link6": ((-0.038, -0.038, -0.038), (0.114, 0.069, 0.058)),
    "link7": ((-0.037, -0.052, -0.028), (0.037, 0.037, 0.0)),
}


@pytest.fixture(scope="module")
def urdf() -> yourdfpy.URDF:
    return yourdfpy.URDF.load(io.StringIO(reference_urdf()), load_meshes=False)


def _rpy_matrix(xyz: tuple[float, ...], rpy: tuple[float, ...]) -> FloatArray:
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    t = np.eye(4)
    t[:3, :3] = rz @ ry @ rx
    t[:3, 3] = xyz
    return t


def _element_shape(collision: yourdfpy.Collision) -> tuple[Shape, FloatArray]:
    g = collision.geometry
    if g.box is not None:
        shape = Shape(ShapeKind.BOX, tuple(float(v) for v in g.box.size))
    elif g.cylinder is not None:
        shape = Shape(ShapeKind.CYLINDER, (g.cylinder.radius, g.cylinder.length))
    else:
        shape = Shape(ShapeKind.SPHERE, (g.sphere.radius,))
    origin = collision.origin if collision.origin is not None else np.eye(4)
    return shape, origin


def _fcl(shape: Shape, pose: FloatArray) -> fcl.CollisionObject:
    return fcl.CollisionObject(shape.to_fcl(), fcl.Transform(pose[:3, :3], pose[:3, 3]))


def _robot_objects(
    urdf: yourdfpy.URDF, arm: tuple[float, ...], base: tuple[float, float, float] = (0, 0, 0)
) -> dict[str, list[fcl.CollisionObject]]:
    urdf.update_cfg(np.asarray(arm, dtype=float))
    world = _rpy_matrix((base[0], base[1], 0.0), (0.0, 0.0, base[2]))
    out: dict[str, list[fcl.CollisionObject]] = {}
    for name, link in urdf.link_map.items():
        link_pose = world @ urdf.get_transform(frame_to=name, frame_from=urdf.base_link)
        for collision in link.collisions:
            shape, origin = _element_shape(collision)
            out.setdefault(name, []).append(_fcl(shape, link_pose @ origin))
    return out


def _distance(a: list[fcl.CollisionObject], b: list[fcl.CollisionObject]) -> float:
    return min(
        fcl.distance(x, y, fcl.DistanceRequest(), fcl.DistanceResult()) for x in a for y in b
    )


def _scene_objects(scene: Scene) -> dict[str, fcl.CollisionObject]:
    return {o.id: _fcl(o.shape, o.pose) for o in scene.objects}


# --- robot -----------------------------------------------------------------------------------


def test_urdf_matches_the_joint_table(urdf: yourdfpy.URDF) -> None:
    assert urdf.actuated_joint_names == list(ARM_JOINT_NAMES)
    for name, (xyz, rpy, lower, upper) in zip(ARM_JOINT_NAMES, JOINT_TABLE, strict=True):
        joint = urdf.joint_map[name]
        assert joint.type == "revolute"
        np.testing.assert_allclose(joint.origin, _rpy_matrix(xyz, rpy), atol=1e-12)
        np.testing.assert_allclose(joint.axis, [0, 0, 1])
        assert joint.limit.lower == pytest.approx(lower, abs=1e-9)
        assert joint.limit.upper == pytest.approx(upper, abs=1e-9)
        assert joint.limit.velocity == pytest.approx(3.14)
    chain = [urdf.joint_map[n] for n in ARM_JOINT_NAMES]
    assert [j.parent for j in chain] == ["link_base", *(f"link{i}" for i in range(1, 7))]
    assert urdf.base_link == "base_link"
    assert urdf.joint_map["tool_mount"].parent == "link7"


def test_base_box_and_tool(urdf: yourdfpy.URDF) -> None:
    (base,) = urdf.link_map["base_link"].collisions
    np.testing.assert_allclose(base.geometry.box.size, BASE_SIZE)
    np.testing.assert_allclose(base.origin[:3, 3], [0, 0, 0.20])
    urdf.update_cfg(np.zeros(7))
    tip = urdf.get_transform("tool_tip", "link7")
    np.testing.assert_allclose(tip[:3, 3], [0, 0, 0.15])
    assert len(urdf.link_map["tool"].collisions) >= 2


@pytest.mark.parametrize("link", sorted(LINK_BOXES))
def test_link_geometry_matches_reference_bounding_box(urdf: yourdfpy.URDF, link: str) -> None:
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    elements = urdf.link_map[link].collisions
    assert 1 <= len(elements) <= 3
    for collision in elements:
        shape, origin = _element_shape(collision)
        extent = np.abs(origin[:3, :3]) @ shape.half_extents()
        lo, hi = np.minimum(lo, origin[:3, 3] - extent), np.maximum(hi, origin[:3, 3] + extent)
    ref_lo, ref_hi = (np.array(v) for v in LINK_BOXES[link])
    np.testing.assert_allclose(lo, ref_lo, atol=0.01)
    np.testing.assert_allclose(hi, ref_hi, atol=0.01)


@pytest.mark.parametrize("arm", [STOWED_ARM, (0.0,) * 7], ids=["stowed", "zero"])
def test_no_self_collision(urdf: yourdfpy.URDF, arm: tuple[float, ...]) -> None:
    objects = _robot_objects(urdf, arm)
    adjacent = {frozenset((j.parent, j.child)) for j in urdf.robot.joints}
    for a, b in itertools.combinations(objects, 2):
        if frozenset((a, b)) not in adjacent:
            assert _distance(objects[a], objects[b]) > 0.02, (a, b)


def test_stowed_arm_stays_inside_the_footprint(urdf: yourdfpy.URDF) -> None:
    urdf.update_cfg(np.asarray(STOWED_ARM))
    for name in (f"link{i}" for i in range(2, 8)):
        for collision in urdf.link_map[name].collisions:
            shape, origin = _element_shape(collision)
            pose = urdf.get_transform(frame_to=name, frame_from="base_link") @ origin
            extent = np.abs(pose[:3, :3]) @ shape.half_extents()
            assert np.all(np.abs(pose[:2, 3]) + extent[:2] <= np.array(BASE_SIZE[:2]) / 2)
            assert pose[2, 3] - extent[2] > BASE_SIZE[2] + 0.05


@pytest.mark.parametrize("doors", [0.0, 90.0])
@pytest.mark.parametrize("seats", [0.0, 90.0])
def test_stowed_robot_is_free_at_every_station(
    urdf: yourdfpy.URDF, doors: float, seats: float
) -> None:
    scene = _scene_objects(restroom_scene(doors=doors, seats=seats))
    for station in RESTROOM_LAYOUT.stations:
        robot = _robot_objects(urdf, STOWED_ARM, station.pose)
        for link, elements in robot.items():
            for oid, obj in scene.items():
                assert _distance(elements, [obj]) > 0.05, (station.name, link, oid)


def test_door_sweep_clears_the_stations_even_when_jittered() -> None:
    base = Shape(ShapeKind.BOX, BASE_SIZE)
    stations = [
        _fcl(base, _rpy_matrix((s.x, s.y, BASE_SIZE[2] / 2), (0, 0, s.theta)))
        for s in RESTROOM_LAYOUT.stations
    ]
    for seed, angle in enumerate(range(0, 91, 5)):
        scene = _scene_objects(restroom_scene(doors=angle, seed=seed, jitter_m=0.03))
        for i in (1, 2, 3):
            door = [scene[f"stall_{i}_door"], scene[f"stall_{i}_door_handle"]]
            assert _distance(stations, door) > 0.05, (i, angle)


def test_reference_model_loads() -> None:
    model = reference_model()
    assert model.dof == 10
    assert model.state_names[:3] == ("base_x", "base_y", "base_theta")
    assert model.joint_names == ARM_JOINT_NAMES
    assert reference_model() is model


# --- restroom --------------------------------------------------------------------------------


def test_restroom_size_and_stable_ids() -> None:
    scene = restroom_scene()
    ids = [o.id for o in scene.objects]
    assert 40 <= len(ids) <= 70
    assert len(set(ids)) == len(ids)
    for oid in ("wall_north", "wall_south", "wall_east", "wall_west", "stall_2_door"):
        assert oid in ids
    for i in (1, 2, 3):
        for part in ("bowl", "tank", "seat"):
            assert f"toilet_{i}_{part}" in ids
    assert {"sink_counter", "sink_1_basin", "hand_dryer"} <= set(ids)
    assert not any("floor" in oid for oid in ids)
    variant = restroom_scene(doors=[10, 50, 90], seats=[0, 45, 90], seed=4, jitter_m=0.02)
    assert [o.id for o in variant.objects] == ids
    assert restroom_scene().hash == scene.hash


def test_door_angle_moves_only_that_door_and_sets_env() -> None:
    closed, opened = restroom_scene(), restroom_scene(doors=[0, 90, 0])
    assert opened.env["stall_2_door"] == pytest.approx(HALF_PI)
    assert closed.env["stall_2_door"] == 0.0 and opened.env["stall_1_door"] == 0.0
    assert opened.hash != closed.hash
    pairs = zip(closed.objects, opened.objects, strict=True)
    moved = {a.id for a, b in pairs if not np.allclose(a.pose, b.pose)}
    assert moved == {"stall_2_door", "stall_2_door_handle"}
    door = {o.id: o for o in opened.objects}["stall_2_door"].pose
    hinge = STALL_FRONTS[1].hinge
    np.testing.assert_allclose(door[:2, 3], [hinge[0], hinge[1] - 0.4], atol=1e-9)  # swung out
    np.testing.assert_allclose(np.abs(door[:3, 0]), [0, 1, 0], atol=1e-12)


def test_seat_angle_lifts_the_seat() -> None:
    down, up = restroom_scene(seats=0), restroom_scene(seats=90)
    seat_down = {o.id: o for o in down.objects}["toilet_3_seat"].pose
    seat_up = {o.id: o for o in up.objects}["toilet_3_seat"].pose
    assert seat_up[2, 3] > seat_down[2, 3] + 0.15
    np.testing.assert_allclose(np.abs(seat_up[:3, 1]), [0, 0, 1], atol=1e-12)  # depth now vertical
    assert up.env["stall_3_seat"] == pytest.approx(HALF_PI)


def test_jitter_is_seeded_and_bounded() -> None:
    nominal = restroom_scene()
    a = restroom_scene(seed=7, jitter_m=0.03)
    assert a.hash == restroom_scene(seed=7, jitter_m=0.03).hash
    assert a.hash != restroom_scene(seed=8, jitter_m=0.03).hash
    for n, j in zip(nominal.objects, a.objects, strict=True):
        shift = j.pose[:3, 3] - n.pose[:3, 3]
        assert 0.01 - 1e-9 <= np.linalg.norm(shift[:2]) <= 0.03 + 1e-9
        assert shift[2] == 0.0


def test_offsets_and_bad_arguments() -> None:
    nominal = restroom_scene()
    shifted = restroom_scene(offsets=np.array([0.1, 0.0, 0.0]))
    for n, s in zip(nominal.objects, shifted.objects, strict=True):
        np.testing.assert_allclose(s.pose[:3, 3] - n.pose[:3, 3], [0.1, 0, 0], atol=1e-12)
    with pytest.raises(SceneError):
        restroom_scene(doors=[0, 90])
    with pytest.raises(SceneError):
        restroom_scene(doors=120)
    with pytest.raises(SceneError):
        restroom_scene(offsets=np.zeros((2, 3)))


def test_restroom_round_trips_through_payload_and_moveit() -> None:
    scene = restroom_scene(doors=[0, 30, 90], seats=45)
    assert parse_scene(scene_to_payload(scene)).hash == scene.hash
    assert parse_scene({**scene_to_moveit(scene), "env": scene.env}).hash == scene.hash


def test_layout_constants() -> None:
    layout = restroom_layout()
    assert layout.room_min == (0.0, 0.0) and layout.room_max == (6.0, 4.0)
    assert len(layout.stall_fronts) == 3
    assert {s.name for s in layout.stations} == {"stall_1", "stall_2", "stall_3", "sink"}
    for front in layout.stall_fronts:
        station = layout.station(f"stall_{front.index}")
        to_door = np.subtract(front.door_centre, (station.x, station.y))
        assert np.dot(to_door, front.facing) > 1.0  # the station faces the stall, > 1 m away
        heading = (math.cos(station.theta), math.sin(station.theta))
        np.testing.assert_allclose(heading, front.facing, atol=1e-12)
        assert front.door_centre[1] - station.y >= 1.0  # ≥ 1.3 m of floor in front of stalls
    sink = layout.station("sink")
    assert sink.y - layout.sink[1] < 1.0
