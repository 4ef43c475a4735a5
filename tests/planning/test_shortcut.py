"""Shortcutting on seeded 2-D paths around a wall with a gap: never colliding, never longer."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tests.planning.test_rris import Geometry
from tests.waiting import NEVER_BINDS_S
from trajcache.geometry.model.shapes import FloatArray
from trajcache.planning.shortcut import (
    END_REACH,
    anchor_ends,
    path_length,
    remove_redundant,
    shortcut,
    shortcut_and_certify,
)

# The wall at x ∈ [4.5, 5.5] with its gap at y ∈ [4.5, 5.5], as two closed boxes.
WALL_BOXES = (
    (np.array([4.5, -1e9]), np.array([5.5, 4.5])),
    (np.array([4.5, 5.5]), np.array([5.5, 1e9])),
)


def hits_box(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Exact segment–box intersection (slab clipping)."""
    t0, t1 = 0.0, 1.0
    d = b - a
    for k in range(2):
        if abs(d[k]) < 1e-15:
            if not lo[k] <= a[k] <= hi[k]:
                return False
            continue
        ta, tb = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return False
    return True


class ExactGeometry(Geometry):
    """The 2-D wall world with exact segment checks, so "never collides" is checked exactly."""

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        self.segment_calls += 1
        return not any(hits_box(a, b, lo, hi) for lo, hi in WALL_BOXES)


def distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(b - a))


def interpolate(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    return a + t * (b - a)


def wiggly_path(rng: np.random.Generator) -> list[np.ndarray]:
    """A valid but wasteful path from (1, 1) through the gap at (5, 5) to (9, 1)."""
    anchors = [np.array([1.0, 1.0]), np.array([4.0, 5.0]), np.array([6.0, 5.0])]
    anchors.append(np.array([9.0, 1.0]))
    geometry = ExactGeometry()
    path = [anchors[0]]
    for a, b in itertools.pairwise(anchors):
        for t in np.linspace(0.0, 1.0, 6)[1:]:
            point = interpolate(a, b, t)
            if t < 1.0:
                candidate = point + rng.normal(0.0, 0.4, 2)
                if geometry.segment_free(path[-1], candidate) and geometry.segment_free(
                    candidate, b
                ):
                    point = candidate
            path.append(point)
    return path


def dense_free(path: list[np.ndarray]) -> bool:
    """Every segment misses the wall (exact check)."""
    geometry = ExactGeometry()
    return all(geometry.segment_free(a, b) for a, b in itertools.pairwise(path))


@pytest.mark.parametrize("seed", range(8))
def test_shortcut_never_collides_and_never_lengthens(seed: int) -> None:
    rng = np.random.default_rng(seed)
    raw = wiggly_path(rng)
    assert dense_free(raw)
    geometry = ExactGeometry()
    out = shortcut(
        raw,
        segment_free_fn=geometry.segment_free,
        distance_fn=distance,
        interpolate_fn=interpolate,
        budget_s=NEVER_BINDS_S,
        rng=rng,
        max_iters=300,
    )
    assert np.allclose(out[0], raw[0]) and np.allclose(out[-1], raw[-1])
    assert dense_free(out)
    assert path_length(out, distance) <= path_length(raw, distance) + 1e-9
    assert path_length(out, distance) < 0.9 * path_length(raw, distance)  # it did shorten
    assert len(out) < len(raw)


def test_free_space_collapses_to_the_straight_segment() -> None:
    geometry = ExactGeometry()
    raw = [np.array([1.0, 1.0]), np.array([2.0, 3.0]), np.array([3.0, 1.5]), np.array([1.0, 4])]
    out = shortcut(
        raw,
        segment_free_fn=geometry.segment_free,
        distance_fn=distance,
        interpolate_fn=interpolate,
        budget_s=NEVER_BINDS_S,
        rng=np.random.default_rng(0),
    )
    assert len(out) == 2
    assert np.allclose(out[0], raw[0]) and np.allclose(out[1], raw[-1])


def test_remove_redundant_keeps_needed_corners() -> None:
    geometry = ExactGeometry()
    corner_path = [
        np.array([1.0, 5.0]),
        np.array([3.0, 5.0]),  # redundant: (1, 5) sees (5, 5) through nothing
        np.array([5.0, 5.0]),
        np.array([7.0, 5.0]),
        np.array([9.0, 9.0]),
    ]
    out = remove_redundant(corner_path, segment_free_fn=geometry.segment_free)
    assert len(out) < len(corner_path)
    assert dense_free(out)
    blocked = [np.array([1.0, 1.0]), np.array([5.0, 5.0]), np.array([9.0, 1.0])]
    assert len(remove_redundant(blocked, segment_free_fn=geometry.segment_free)) == 3


def test_zero_budget_does_no_work_and_stays_valid() -> None:
    rng = np.random.default_rng(1)
    raw = wiggly_path(rng)
    geometry = ExactGeometry()
    checked: list[tuple[FloatArray, FloatArray]] = []

    def counted(a: FloatArray, b: FloatArray) -> bool:
        checked.append((a, b))
        return geometry.segment_free(a, b)

    drawn = rng.bit_generator.state
    out = shortcut(
        raw,
        segment_free_fn=counted,
        distance_fn=distance,
        interpolate_fn=interpolate,
        budget_s=0.0,
        rng=rng,
    )
    assert checked == [] and rng.bit_generator.state == drawn  # no check, no random try
    assert dense_free(out)
    assert path_length(out, distance) <= path_length(raw, distance) + 1e-9


def test_finishing_falls_back_to_the_raw_path_when_the_shortcut_fails_validation() -> None:
    raw = wiggly_path(np.random.default_rng(2))
    anchored = anchor_ends(raw, distance_fn=distance, interpolate_fn=interpolate)
    geometry = ExactGeometry()
    seen: list[int] = []

    def validate(path: np.ndarray) -> tuple[bool, str]:
        seen.append(len(path))
        return len(path) == len(anchored), "too short for this test"

    finished = shortcut_and_certify(
        raw,
        segment_free_fn=geometry.segment_free,
        distance_fn=distance,
        interpolate_fn=interpolate,
        validate_fn=validate,
        budget_s=NEVER_BINDS_S,
        rng=np.random.default_rng(0),
    )
    assert finished.path is not None and len(finished.path) == len(anchored)
    assert seen == [seen[0], len(anchored)] and seen[0] < len(anchored)
    assert finished.stats["shortcut_rejected"] == 1.0
    assert finished.stats["length_after"] == pytest.approx(finished.stats["length_before"])

    rejected = shortcut_and_certify(
        raw,
        segment_free_fn=geometry.segment_free,
        distance_fn=distance,
        interpolate_fn=interpolate,
        validate_fn=lambda path: (False, "nope"),
        budget_s=NEVER_BINDS_S,
        rng=np.random.default_rng(0),
    )
    assert rejected.path is None and "nope" in rejected.message
    assert 2 <= len(rejected.short) < len(raw)  # the shortcut path, for a repair to mend


def test_end_anchors_lie_on_the_end_segments_and_keep_the_motion() -> None:
    """An anchor END_REACH along the first and the last segment, where they are long enough;
    the same states otherwise, and the same length."""
    path = [
        np.array([0.0, 0.0]),
        np.array([1.0, 0.0]),
        np.array([1.0, 0.15]),
        np.array([3.0, 0.15]),
    ]
    out = anchor_ends(path, distance_fn=distance, interpolate_fn=interpolate)
    assert len(out) == 6
    np.testing.assert_allclose(out[1], [END_REACH, 0.0])
    np.testing.assert_allclose(out[-2], [3.0 - END_REACH, 0.15])
    for kept, state in zip(path, [out[0], out[2], out[3], out[5]], strict=True):
        np.testing.assert_array_equal(kept, state)
    assert path_length(out, distance) == pytest.approx(path_length(path, distance))
    short = [np.array([0.0, 0.0]), np.array([0.15, 0.0])]
    assert len(anchor_ends(short, distance_fn=distance, interpolate_fn=interpolate)) == 2
