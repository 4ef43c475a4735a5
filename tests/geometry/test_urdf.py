"""URDF loading: structure, limits, meshes from archives, safety, model ids and allowed pairs."""

from __future__ import annotations

import io
import math
import tarfile
import zipfile

import numpy as np
import pytest
import trimesh

from tests.robots import (
    ARM_URDF,
    SWING_URDF,
    UNLIMITED_URDF,
    mesh_robot,
    upright_chain,
    with_mimic,
)
from trajcache.geometry.errors import MeshError, RobotModelError, UnsafePathError
from trajcache.geometry.model.files import unpack_archive
from trajcache.geometry.model.robot import BaseType, CollisionElement
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model


def _box_bytes(kind: str, extents: tuple[float, float, float] = (0.1, 0.2, 0.3)) -> bytes:
    exported = trimesh.creation.box(extents=extents).export(file_type=kind)
    return exported.encode() if isinstance(exported, str) else bytes(exported)


def _zip(entries: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, content in entries.items():
            archive.writestr(zipfile.ZipInfo(name), content)
    return buffer.getvalue()


def test_links_joints_and_limits_follow_the_tree() -> None:
    model = load_robot_model(ARM_URDF)
    assert model.link_names[0] == "base_link"
    assert model.joint_names == ("j4", "j1", "j2", "slide", "flag_joint")  # URDF order
    seen = {0}
    for joint in model.joints:  # parents before children
        assert joint.parent in seen
        seen.add(joint.child)
    index = {j.name: j.index for j in model.joints}
    assert index == {"mount_fixed": -1, "j1": 1, "cam_fixed": -1, "j2": 2, "slide": 3,
                     "j4": 0, "tool_fixed": -1, "flag_joint": 4}  # fmt: skip
    np.testing.assert_allclose(model.lower, [-math.pi, -2.5, -math.pi, -0.1, 0.2])
    np.testing.assert_allclose(model.upper, [math.pi, 2.5, math.pi, 0.2, 1.0])
    np.testing.assert_allclose(model.velocity_limits, [2.5, 2.0, 3.14, 0.3, 1.0])
    assert len(model.elements) == 9 and model.name == "test_arm"


def test_planar_base_and_held_joints() -> None:
    model = load_robot_model(ARM_URDF, base="planar", joint_names=["j1", "j2"], name="r")
    assert model.base is BaseType.PLANAR and model.name == "r"
    assert model.state_names == ("base_x", "base_y", "base_theta", "j1", "j2")
    np.testing.assert_allclose(model.lower[:3], [-np.inf, -np.inf, -math.pi])
    np.testing.assert_allclose(model.upper[:3], [np.inf, np.inf, math.pi])
    np.testing.assert_allclose(model.velocity_limits[:3], [0.5, 0.5, 1.0])
    joints = {j.name: j for j in model.joints}
    assert (joints["j1"].index, joints["j2"].index) == (3, 4)
    assert joints["flag_joint"].index == -1 and joints["flag_joint"].default == 0.2  # clipped
    assert joints["slide"].default == 0.0


def test_unknown_and_fixed_joint_names_are_refused() -> None:
    with pytest.raises(RobotModelError, match="nope"):
        load_robot_model(ARM_URDF, joint_names=["j1", "nope"])
    with pytest.raises(RobotModelError, match="tool_fixed"):
        load_robot_model(ARM_URDF, joint_names=["tool_fixed"])
    with pytest.raises(RobotModelError, match="base type"):
        load_robot_model(ARM_URDF, base="holonomic")


def test_model_id_is_a_content_hash() -> None:
    first = load_robot_model(ARM_URDF)
    assert load_robot_model("\n" + ARM_URDF + "  \n").model_id == first.model_id
    assert len(first.model_id) == 64
    others = {
        load_robot_model(ARM_URDF.replace('velocity="2.0"', 'velocity="2.1"')).model_id,
        load_robot_model(ARM_URDF, base="planar").model_id,
        load_robot_model(ARM_URDF, joint_names=["j1"]).model_id,
    }
    assert first.model_id not in others and len(others) == 3


def test_meshes_resolve_package_and_relative_uris_from_a_zip() -> None:
    files = unpack_archive(
        _zip({"my_pkg/meshes/a.stl": _box_bytes("stl"), "meshes/b.obj": _box_bytes("obj")})
    )
    assert set(files) == {"my_pkg/meshes/a.stl", "meshes/b.obj"}
    urdf = mesh_robot(
        "package://my_pkg/meshes/a.stl", "package://other/meshes/b.obj", "./meshes/b.obj"
    )
    model = load_robot_model(urdf.replace('scale="1 1 1"', 'scale="2 1 0.5"', 1), files=files)
    assert [e.shape.kind for e in model.elements] == [ShapeKind.MESH] * 3
    np.testing.assert_allclose(model.elements[0].shape.half_extents(), [0.1, 0.1, 0.075])
    np.testing.assert_allclose(model.elements[2].shape.half_extents(), [0.05, 0.1, 0.15])
    base_id = load_robot_model(urdf, files=files).model_id
    assert load_robot_model(urdf, files={**files, "unused.stl": b"x"}).model_id == base_id
    changed = {**files, "meshes/b.obj": _box_bytes("obj", (0.1, 0.2, 0.4))}
    assert load_robot_model(urdf, files=changed).model_id != base_id


@pytest.mark.parametrize(
    "uri",
    ["package://x/../../etc/passwd", "../a.stl", "/etc/passwd", "file:///etc/passwd",
     "C:\\meshes\\a.stl", "http://example.com/a.stl"],
)  # fmt: skip
def test_mesh_uris_cannot_escape(uri: str) -> None:
    with pytest.raises(UnsafePathError):
        load_robot_model(mesh_robot(uri), files={"a.stl": _box_bytes("stl")})


def test_missing_and_unreadable_meshes() -> None:
    with pytest.raises(MeshError, match=r"package://p/missing\.stl"):
        load_robot_model(mesh_robot("package://p/missing.stl"), files={})
    with pytest.raises(MeshError, match=r"broken\.stl"):
        load_robot_model(mesh_robot("broken.stl"), files={"broken.stl": b"not a mesh"})


def test_entity_expansion_is_refused_before_expanding() -> None:
    # Literals: the entities are what is tested.
    lol = "".join(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10))
    bomb = f'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY l0 "lol">{lol}]><robot name="&l9;"/>'
    with pytest.raises(RobotModelError, match="DOCTYPE"):
        load_robot_model(bomb)  # refused for its DOCTYPE: nothing was expanded
    external = '<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="&x;"/>'
    with pytest.raises(RobotModelError, match="DOCTYPE"):
        load_robot_model(external)


# Literals: each malformation is what is tested.
@pytest.mark.parametrize(
    ("urdf", "message"),
    [
        ('<robot name="r"><link name="a"></robot>', "malformed"),
        ('<robot name="r"/>', "no <link>"),
        ("<model/>", "expected <robot>"),
        ('<robot><link name="a"/></robot>', "no name"),
        ('<robot name="r"><link name="a"/><link name="b"/></robot>', "several root"),
        (
            '<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
            '<joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>'
            '<joint name="y" type="fixed"><parent link="c"/><child link="c"/></joint></robot>',
            "cycle",
        ),
        (
            '<robot name="r"><link name="a"/><link name="b"/>'
            '<joint name="x" type="floating"><parent link="a"/><child link="b"/></joint></robot>',
            "floating",
        ),
        (
            '<robot name="r"><link name="a"/>'
            '<joint name="x" type="fixed"><parent link="a"/><child link="zz"/></joint></robot>',
            "zz",
        ),
        (
            '<robot name="r"><link name="a"/><link name="b"/>'
            '<joint name="x" type="prismatic"><parent link="a"/><child link="b"/></joint></robot>',
            "no <limit>",
        ),
        (
            '<robot name="r"><link name="a"><collision><geometry><capsule radius="1" length="1"/>'
            "</geometry></collision></link></robot>",
            "capsule",
        ),
        (
            '<robot name="r"><link name="a"><collision><geometry><box size="1 1"/>'
            "</geometry></collision></link></robot>",
            "box",
        ),
    ],
)
def test_broken_urdfs_are_refused_with_a_reason(urdf: str, message: str) -> None:
    with pytest.raises(RobotModelError, match=message):
        load_robot_model(urdf)


def test_mimic_joints_follow_their_held_leader_and_are_refused_when_planned() -> None:
    urdf = with_mimic(ARM_URDF, follower="flag_joint", leader="j1", multiplier=0.5, offset=0.3)
    with pytest.raises(RobotModelError, match="mimic"):
        load_robot_model(urdf)  # its leader is planned: the follower would have to move with it
    held = load_robot_model(urdf, joint_names=["j2"], joint_values={"j1": 0.8})
    assert held.held_values["flag_joint"] == pytest.approx(0.5 * 0.8 + 0.3)
    assert {j.name: j.default for j in held.joints}["flag_joint"] == pytest.approx(0.7)
    with pytest.raises(RobotModelError, match="mimics"):
        load_robot_model(urdf, joint_names=["j2"], joint_values={"flag_joint": 0.5})


def test_unpack_archive_handles_tar_and_refuses_unsafe_entries() -> None:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        for name in ("pkg/", "pkg/./m.stl"):
            info = tarfile.TarInfo(name)
            info.type = tarfile.DIRTYPE if name.endswith("/") else tarfile.REGTYPE
            info.size = 0 if name.endswith("/") else 3
            tar.addfile(info, io.BytesIO(b"abc"))
    assert unpack_archive(buffer.getvalue()) == {"pkg/m.stl": b"abc"}
    for name in ("../evil.stl", "/abs.stl", "a/../../evil.stl"):
        with pytest.raises(UnsafePathError):
            unpack_archive(_zip({name: b"x"}))
    link_info = zipfile.ZipInfo("link.stl")
    link_info.external_attr = 0o120777 << 16
    with pytest.raises(UnsafePathError, match="symbolic link"):
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w") as archive:
            archive.writestr(link_info, "/etc/passwd")
        unpack_archive(buffer.getvalue())
    for link_type in (tarfile.SYMTYPE, tarfile.LNKTYPE):
        buffer = io.BytesIO()
        with tarfile.open(fileobj=buffer, mode="w") as tar:
            info = tarfile.TarInfo("link.stl")
            info.type, info.linkname = link_type, "/etc/passwd"
            tar.addfile(info)
        with pytest.raises(UnsafePathError, match="link"):
            unpack_archive(buffer.getvalue())
    with pytest.raises(RobotModelError, match="entries"):
        unpack_archive(_zip({f"f{i}": b"" for i in range(5)}), max_entries=4)
    with pytest.raises(RobotModelError, match="exceeds"):
        unpack_archive(_zip({"a": b"x" * 600, "b": b"y" * 600}), max_total_bytes=1000)
    with pytest.raises(RobotModelError):
        unpack_archive(b"definitely not an archive")


def test_joints_without_limits_turn_freely_or_are_held() -> None:
    model = load_robot_model(UNLIMITED_URDF, joint_names=["x"], joint_values={"y": 0.25})
    assert (model.lower[0], model.upper[0]) == (-math.pi, math.pi)
    assert model.held_values == {"y": 0.25}


def test_only_adjacent_and_rigid_pairs_are_skipped_without_an_srdf() -> None:
    model = load_robot_model(SWING_URDF)
    idx = {name: i for i, name in enumerate(model.link_names)}

    def pair(a: str, b: str) -> tuple[int, int]:
        return min(idx[a], idx[b]), max(idx[a], idx[b])

    assert model.pair_reasons == {
        pair("base_link", "upper"): "adjacent",
        pair("upper", "fore"): "adjacent",
        pair("base_link", "mast"): "adjacent",  # one rigid body (a fixed joint)
        pair("mast", "upper"): "adjacent",  # through the rigid base body
    }
    # Never in reach is no reason to skip "mast"–"fore" here: only a proof is (free_pairs).
    assert pair("mast", "fore") not in model.allowed_pairs
    assert model.allowed_pairs == frozenset(model.pair_reasons)


def test_adjacency_passes_through_links_without_geometry() -> None:
    urdf = upright_chain(4, bare=(2,))
    reasons = load_robot_model(urdf).pair_reasons
    assert reasons == {(0, 1): "adjacent", (1, 3): "adjacent"}  # l1–l3 through bare l2


def test_a_mesh_element_is_centred_on_its_box_with_its_geometry_unchanged() -> None:
    vertices = np.array([[1.0, 2.0, 0.0], [1.2, 2.0, 0.0], [1.0, 2.3, 0.0], [1.0, 2.0, 0.1]])
    shape = Shape(ShapeKind.MESH, vertices=vertices, faces=np.array([[0, 1, 2], [0, 1, 3]]))
    origin = np.eye(4)
    origin[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    origin[:3, 3] = [0.5, 0.0, 0.2]
    element = CollisionElement.placed(3, shape, origin)
    assert element.shape.vertices is not None
    placed = element.shape.vertices @ element.origin[:3, :3].T + element.origin[:3, 3]
    np.testing.assert_allclose(placed, vertices @ origin[:3, :3].T + origin[:3, 3], atol=1e-12)
    np.testing.assert_allclose(
        element.shape.vertices.min(axis=0), -element.shape.vertices.max(axis=0), atol=1e-12
    )
    assert element.shape.bounding_radius() < 0.25 < shape.bounding_radius()
