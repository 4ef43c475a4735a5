"""The certifier's compiled first try (`validation/settle.py`): it certifies only chains that
the certifier's stages certify and that a 20× denser check finds free, and it settles most."""

from __future__ import annotations

import numpy as np
import pytest

from tests.geometry.test_certify import _dense_collides, _near_motions, _rod_and_plate
from tests.geometry.test_validation import _plate
from tests.robots import ROD_URDF
from trajcache.geometry.model.space import segment_deltas
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import make_scene
from trajcache.geometry.validation.segments import SegmentStatus
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import reference_model


def _settle(validator: TrajectoryValidator, samples: np.ndarray) -> int | None:
    certifier = validator.certifier
    delta = segment_deltas(samples, base=validator.model.base)
    return certifier.settler.free(samples, delta, certifier.robot.motion.steps(delta))


def test_it_certifies_only_what_the_stages_and_a_denser_check_find_free(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    model = reference_model()
    scene = restroom_scene(doors=(10, 50, 90), seats=(90, 0, 0))
    validator = TrajectoryValidator(model, scene)
    stages = TrajectoryValidator(model, scene)
    monkeypatch.setattr(stages.certifier.settler, "free", lambda *_: None)
    counts = {"settled": 0, "left": 0, "advanced": 0, "stages_free": 0}
    for key in _near_motions(model, scene, np.random.default_rng(8), 60):
        samples = interpolate(key, model, Resolution())
        probes = _settle(validator, samples)
        verdict = stages.certifier.certify(samples).status
        counts["stages_free"] += verdict is SegmentStatus.FREE
        if probes is None:
            counts["left"] += 1
            continue
        counts["settled"] += 1
        counts["advanced"] += probes > 0
        assert verdict is SegmentStatus.FREE
        assert not _dense_collides(validator, key, factor=20)
    assert counts["left"] > 5, counts  # colliding and too-close motions are the stages' to say
    assert counts["settled"] >= 0.9 * counts["stages_free"], counts
    assert counts["advanced"] > 0, counts  # some needed advancement between samples


def test_a_collision_between_samples_is_left_to_the_stages() -> None:
    """The rod sweeps through its own plate between two samples: the compiled call must not
    certify it, and validation finds the self-collision there."""
    key = np.array([[0.0, 0.0], [1.0, 0.0]])
    samples = interpolate(key, _rod_and_plate(0.0), Resolution())
    model = _rod_and_plate(float(samples[10, 0] + samples[11, 0]) / 2.0)
    validator = TrajectoryValidator(model, make_scene([]))
    assert _settle(validator, samples) is None
    assert _settle(validator, samples[:10]) is not None  # before the plate it is free
    assert not validator.validate(key).valid


@pytest.mark.parametrize("radius", [0.9, 1.0])
def test_a_thin_plate_between_samples_is_left_to_the_stages(radius: float) -> None:
    """A 2 mm plate between two samples, across the rod or at its tip: free at every sample,
    hit between them; advancement must not certify the segment past it."""
    swing = load_robot_model(ROD_URDF)
    key = np.array([[0.0], [1.0]])
    samples = interpolate(key, swing, Resolution())
    scene = _plate((samples[10, 0] + samples[11, 0]) / 2.0, radius)
    validator = TrajectoryValidator(swing, scene)
    assert TrajectoryValidator(swing, scene, certified=False).validate(key).valid
    assert _settle(validator, samples) is None
    assert validator.validate(key).status.value == "collision"
