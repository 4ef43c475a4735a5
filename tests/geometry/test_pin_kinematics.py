"""Pinocchio's model of a registered URDF agrees with the service's own forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from tests.robots import ARM_URDF, with_mimic
from trajcache.geometry.errors import RobotModelError
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import reference_model, reference_urdf

MIMIC_URDF = with_mimic(ARM_URDF, follower="flag_joint", leader="j1", multiplier=0.5, offset=0.3)


def _example(name: str, **overrides: object) -> tuple[RobotModel, str]:
    robot = ROBOTS[name]
    fields: dict[str, object] = {"srdf": robot.srdf, "group": robot.group, "base": robot.base}
    if robot.joint_names is not None:
        fields["joint_names"] = list(robot.joint_names)
    fields.update(overrides)
    return load_robot_model(robot.urdf, files=robot.files(), **fields), robot.urdf  # type: ignore[arg-type]


def _states(model: RobotModel, n: int, seed: int) -> FloatArray:
    lower = np.where(np.isfinite(model.lower), model.lower, -2.0)
    upper = np.where(np.isfinite(model.upper), model.upper, 2.0)
    return np.random.default_rng(seed).uniform(lower, upper, size=(n, model.dof))


def _assert_agree(model: RobotModel, urdf: str) -> None:
    kinematics = PinKinematics.build(model, urdf)
    for state in _states(model, 8, 3):
        poses = link_transforms(model, state)[0]
        for link, name in enumerate(model.link_names):
            got = kinematics.link_pose(state, kinematics.frame_id(name))
            np.testing.assert_allclose(got, poses[link], atol=1e-9, err_msg=name)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_every_example_robot_agrees_link_by_link(name: str) -> None:
    _assert_agree(*_example(name))


def test_the_reference_robot_on_its_planar_base_agrees() -> None:
    _assert_agree(reference_model(), reference_urdf())


def _panda_with_fingers() -> tuple[RobotModel, str]:
    """The Panda planning one finger: the other mimics it."""
    arm = [f"panda_joint{k}" for k in range(1, 8)]
    return _example("panda", group=None, joint_names=[*arm, "panda_finger_joint1"])


def test_a_planned_mimic_leader_moves_its_follower_in_pinocchio_too() -> None:
    _assert_agree(*_panda_with_fingers())


@pytest.mark.parametrize("base", ["fixed", "planar"])
def test_continuous_prismatic_held_and_held_mimic_joints_agree(base: str) -> None:
    _assert_agree(load_robot_model(ARM_URDF, base=base), ARM_URDF)
    held = load_robot_model(MIMIC_URDF, base=base, joint_names=["j2", "slide"])  # j1 held
    _assert_agree(held, MIMIC_URDF)


@pytest.mark.parametrize("robot", ["planar-arm", "panda-fingers"])
def test_the_jacobian_by_state_matches_finite_differences(robot: str) -> None:
    if robot == "planar-arm":
        model, urdf, link = load_robot_model(ARM_URDF, base="planar"), ARM_URDF, "flag"
    else:
        (model, urdf), link = _panda_with_fingers(), "panda_rightfinger"
    kinematics = PinKinematics.build(model, urdf)
    frame = kinematics.frame_id(link)
    state = _states(model, 1, 5)[0]
    data = kinematics.pin_model.createData()
    pin.computeJointJacobians(kinematics.pin_model, data, kinematics.q_of(state))
    pin.updateFramePlacements(kinematics.pin_model, data)
    jacobian = pin.getFrameJacobian(
        kinematics.pin_model, data, frame, pin.LOCAL_WORLD_ALIGNED
    ) @ kinematics.velocity_of(state)
    step = 1e-6
    for d in range(model.dof):
        moved = state.copy()
        moved[d] += step
        ahead = kinematics.link_pose(moved, frame)[:3, 3]
        rate = (ahead - kinematics.link_pose(state, frame)[:3, 3]) / step
        np.testing.assert_allclose(jacobian[:3, d], rate, atol=1e-4, err_msg=model.state_names[d])


def test_an_unknown_link_is_named() -> None:
    model = load_robot_model(ARM_URDF)
    with pytest.raises(RobotModelError, match="no link 'nope'"):
        PinKinematics.build(model, ARM_URDF).frame_id("nope")
