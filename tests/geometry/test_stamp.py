"""Certificates name one verdict: the certifier's source, model, scene, settings and states."""

from __future__ import annotations

import numpy as np

from tests.robots import TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import make_scene
from trajcache.geometry.validation import stamp
from trajcache.geometry.validation.stamp import certificate_digest, certifier_digest
from trajcache.geometry.validation.validator import (
    build_validator,
    certificate_for,
    settings_key_of,
)

STATES = np.array([[0.0, 0.1], [0.5, 0.2]])
SETTINGS = (0.035, True)


def test_the_same_inputs_give_the_same_certificate_and_any_change_another() -> None:
    base = certificate_digest("model", "scene", SETTINGS, STATES)
    assert base == certificate_digest("model", "scene", SETTINGS, STATES.copy())
    moved = STATES.copy()
    moved[1, 1] = np.nextafter(moved[1, 1], 1.0)  # one ulp
    others = {
        certificate_digest("model2", "scene", SETTINGS, STATES),
        certificate_digest("model", "scene2", SETTINGS, STATES),
        certificate_digest("model", "scene", (0.035, False), STATES),
        certificate_digest("model", "scene", SETTINGS, moved),
        certificate_digest("model", "scene", SETTINGS, STATES[::-1]),
        certificate_digest("model", "scene", SETTINGS, STATES.reshape(1, 4)),
    }
    assert base not in others and len(others) == 6


def test_a_scene_without_a_content_hash_gets_no_certificate() -> None:
    assert certificate_digest("model", "", SETTINGS, STATES) == ""


def test_another_certifier_source_gives_another_certificate(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    base = certificate_digest("model", "scene", SETTINGS, STATES)
    (tmp_path / "validation").mkdir()
    (tmp_path / "validation" / "certify.py").write_text("changed = True\n")
    monkeypatch.setattr(stamp, "_GEOMETRY", tmp_path)
    certifier_digest.cache_clear()
    try:
        assert certificate_digest("model", "scene", SETTINGS, STATES) != base
    finally:
        certifier_digest.cache_clear()


def test_a_certificate_named_without_a_validator_is_the_validator_s() -> None:
    model = load_robot_model(TWO_JOINT_URDF, base="fixed")
    scene = make_scene([])
    settings = Settings(step_joint_rad=0.02)
    validator = build_validator(model, scene, settings)
    assert settings_key_of(settings) == validator.settings_key
    assert certificate_for(model, scene, settings, STATES) == validator.certificate(STATES)
    assert certificate_for(model, scene, Settings(), STATES) != validator.certificate(STATES)
