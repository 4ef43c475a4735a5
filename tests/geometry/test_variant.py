"""The model a robot is checked with in a scene: built once per variant, and found again by the
scene's content hash without computing the variant's key."""

from __future__ import annotations

import numpy as np
import pytest

from tests.robots import PINCER_SRDF, PINCER_URDF
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene import variant
from trajcache.geometry.scene.scene import AttachedObject, Scene, SceneObject, make_scene
from trajcache.geometry.scene.variant import model_in_scene, variant_cache


@pytest.fixture(scope="module")
def pincer() -> RobotModel:
    return load_robot_model(PINCER_URDF, srdf=PINCER_SRDF, group="arm")


def _scene(allowed: tuple[str, str] = ("base", "fore"), x: float = 0.0) -> Scene:
    pose = np.eye(4)
    pose[0, 3] = x
    held = AttachedObject("fore", SceneObject("cup", Shape(ShapeKind.SPHERE, (0.02,)), pose))
    return make_scene([], allowed=[allowed], attached=[held])


def test_a_variant_is_found_again_by_the_scene_hash_without_its_key(
    pincer: RobotModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    keys: list[str] = []
    real = variant._variant_key
    monkeypatch.setattr(variant, "_variant_key", lambda *a: keys.append("key") or real(*a))
    cache = variant_cache()
    scene = _scene()
    first = model_in_scene(pincer, scene, {"finger": 0.01}, cache=cache)
    assert first is not pincer and "cup" in first.link_names and len(keys) == 1
    same = _scene()  # another object, the same content: the same hash
    assert model_in_scene(pincer, same, {"finger": 0.01}, cache=cache) is first
    assert len(keys) == 1  # found by the hash and the held values alone
    other_held = model_in_scene(pincer, scene, {"finger": 0.02}, cache=cache)
    moved = model_in_scene(pincer, _scene(x=0.05), {"finger": 0.01}, cache=cache)
    other_pair = model_in_scene(pincer, _scene(("base", "upper")), {"finger": 0.01}, cache=cache)
    variants = {id(v) for v in (first, other_held, moved, other_pair)}
    assert len(variants) == 4 and len(keys) == 4  # each one its own variant, keyed once
    assert model_in_scene(pincer, _scene(x=0.05), {"finger": 0.01}, cache=cache) is moved
    assert len(keys) == 4
