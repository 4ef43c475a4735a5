"""How answers are read: the fields of real robots and scenes, their defaults, newer values."""

from __future__ import annotations

import trajcache_client as tc
from tests.client.test_retries import ROBOT

MODEL = {
    "model_id": "m1",
    "name": "pincer",
    "joint_names": ["shoulder", "elbow"],
    "base": "fixed",
    "state_names": ["shoulder", "elbow"],
    "created": True,
}
SEMANTICS = {
    "skipped_pairs": [
        {"links": ["base", "upper"], "reason": "adjacent"},
        {"links": ["base", "fore"], "reason": "srdf"},
    ],
    "held_joints": {"finger": 0.03},
    "named_states": {"ready": [0.5, -0.4]},
}
DETAIL = {
    **{k: v for k, v in MODEL.items() if k != "created"},
    "created_at": "2025-06-02T09:25:01Z",
    "link_names": ["base", "upper", "fore", "finger"],
    "lower": [-2.0, -1.5],
    "upper": [2.0, 1.5],
    "velocity_limits": [1.0, 1.0],
    "files": [],
}


def test_a_model_answer_lists_skipped_pairs_held_joints_and_named_states() -> None:
    model = tc.RobotModel.model_validate({**MODEL, **SEMANTICS})
    assert model.skipped_pairs == [
        tc.SkippedPair(links=("base", "upper"), reason="adjacent"),
        tc.SkippedPair(links=("base", "fore"), reason="srdf"),
    ]
    assert model.held_joints == {"finger": 0.03} and model.named_states == {"ready": [0.5, -0.4]}
    assert model.model_extra == {}


def test_a_model_detail_carries_the_same_and_its_timing_configuration() -> None:
    timing = {"acceleration_limits": [2.0, 3.0], "jerk_limits": [50.0, 50.0]}
    detail = tc.RobotModelDetail.model_validate(
        {**DETAIL, **SEMANTICS, **timing, "end_effector_link": "fore"}
    )
    assert [(p.links, p.reason) for p in detail.skipped_pairs] == [
        (("base", "upper"), "adjacent"),
        (("base", "fore"), "srdf"),
    ]
    assert detail.held_joints == {"finger": 0.03} and detail.named_states["ready"] == [0.5, -0.4]
    assert detail.acceleration_limits == [2.0, 3.0] and detail.jerk_limits == [50.0, 50.0]
    assert detail.end_effector_link == "fore" and detail.model_extra == {}


def test_models_without_the_new_fields_read_as_empty() -> None:
    model = tc.RobotModel.model_validate(MODEL)
    detail = tc.RobotModelDetail.model_validate(DETAIL)
    for answer in (model, detail):
        assert (answer.skipped_pairs, answer.held_joints, answer.named_states) == ([], {}, {})
    assert detail.acceleration_limits is None and detail.end_effector_link is None


def test_a_skip_reason_a_newer_service_adds_is_kept() -> None:
    pair = {"links": ["base", "fore"], "reason": "scene"}
    model = tc.RobotModel.model_validate({**MODEL, "skipped_pairs": [pair]})
    assert model.skipped_pairs[0].reason == "scene"


def test_a_robot_answer_carries_its_kind_and_held_values() -> None:
    robot = tc.Robot.model_validate({**ROBOT, "kind": "sim", "joint_values": {"finger": 0.01}})
    assert robot.kind == "sim" and robot.joint_values == {"finger": 0.01}
    assert tc.Robot.model_validate(ROBOT).joint_values == {}
    assert tc.Robot.model_validate({**ROBOT, "kind": "twin"}).kind == "twin"


def test_scene_answers_carry_warnings_allowed_collisions_and_attached_objects() -> None:
    warned = tc.SceneVersion.model_validate(
        {"version": 3, "hash": "h", "warnings": ["robot_state.joint_state is not applied"]}
    )
    assert warned.warnings == ["robot_state.joint_state is not applied"]
    rod = {"link": "fore", "object": {"id": "rod", "type": "sphere", "size": [0.02]}}
    scene = tc.Scene.model_validate(
        {
            "version": 3,
            "hash": "h",
            "objects": [],
            "env": {},
            "allowed_collisions": [["finger", "table"]],
            "attached_objects": [rod],
        }
    )
    assert scene.allowed_collisions == [["finger", "table"]] and scene.attached_objects == [rod]
    bare = tc.Scene.model_validate({"version": 1, "hash": "h", "objects": [], "env": {}})
    assert (bare.allowed_collisions, bare.attached_objects) == ([], [])
