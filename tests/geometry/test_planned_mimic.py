"""A mimic joint that follows a planning joint: the Panda's fingers planned as one joint."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.errors import RobotModelError
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.motion import motion_bounds
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import SceneObject, make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.reference.example_robots import ROBOTS

ARM = [f"panda_joint{k}" for k in range(1, 8)]
READY = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398, 0.0])


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    robot = ROBOTS["panda"]
    return load_robot_model(
        robot.urdf, files=robot.files(), srdf=robot.srdf, joint_names=[*ARM, "panda_finger_joint1"]
    )


def _frame(model: RobotModel, state: np.ndarray, link: str) -> np.ndarray:
    return link_transforms(model, state)[0][model.link_names.index(link)]


def test_the_follower_moves_with_its_planned_leader(panda: RobotModel) -> None:
    assert panda.held_values == {}  # panda_finger_joint2 follows a planning joint: not held
    gaps = []
    for opening in (0.0, 0.03):
        state = READY.copy()
        state[7] = opening
        left = _frame(panda, state, "panda_leftfinger")[:3, 3]
        right = _frame(panda, state, "panda_rightfinger")[:3, 3]
        gaps.append(float(np.linalg.norm(left - right)))
    assert gaps[1] - gaps[0] == pytest.approx(0.06, abs=1e-9)
    default = ROBOTS["panda"]  # without joint names, both fingers are planned as one joint
    assert (
        "panda_finger_joint1" in load_robot_model(default.urdf, files=default.files()).joint_names
    )


def test_a_plate_crossed_only_by_the_follower_between_samples_is_caught(panda: RobotModel) -> None:
    # A 1 mm plate 3 cm beside the right finger: it passes through it while the fingers open
    # from 0 to 4 cm, and both ends are clear. Only the follower (panda_finger_joint2) reaches it.
    hand, finger = _frame(panda, READY, "panda_hand"), _frame(panda, READY, "panda_rightfinger")
    pose = np.eye(4)
    pose[:3, :3] = hand[:3, :3]
    pose[:3, 3] = finger[:3, 3] - 0.03 * hand[:3, 1] + 0.03 * hand[:3, 2]
    scene = make_scene([SceneObject("plate", Shape(ShapeKind.BOX, (0.03, 0.001, 0.03)), pose)])
    opened = READY.copy()
    opened[7] = 0.04
    checker = CollisionChecker(panda, scene)
    assert not checker.state_contacts(READY) and not checker.state_contacts(opened)
    result = TrajectoryValidator(panda, scene).validate(np.array([READY, opened]))
    assert not result.valid
    assert "panda_rightfinger" in result.message


@pytest.mark.parametrize(
    ("mimic", "needle"),
    [
        ('<mimic joint="panda_finger_joint1" multiplier="2"/>', "multiplier 2.0"),
        ('<mimic joint="panda_joint7"/>', "only prismatic joints"),
    ],
)
def test_unsupported_planned_mimics_are_named(mimic: str, needle: str) -> None:
    robot = ROBOTS["panda"]
    urdf = robot.urdf.replace('<mimic joint="panda_finger_joint1"/>', mimic)
    with pytest.raises(RobotModelError, match=needle):
        load_robot_model(urdf, files=robot.files(), joint_names=[*ARM, "panda_finger_joint1"])


def test_the_fingers_move_relative_to_each_other_under_their_shared_joint() -> None:
    robot = ROBOTS["panda"]
    model = load_robot_model(robot.urdf, files=robot.files())  # no SRDF: the pair is checked
    left, right = (model.link_names.index(f"panda_{s}finger") for s in ("left", "right"))
    alike = motion_bounds(model).alike(np.array([left]), np.array([right]))[0]
    finger = model.joint_names.index("panda_finger_joint1")
    assert alike[0] and not alike[finger]  # joint 1 swings both alike; the fingers part
    assert (min(left, right), max(left, right)) not in model.pair_reasons
