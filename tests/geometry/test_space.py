"""The state space's one angle wrap, state differences, path length and still-base test."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.space import (
    BASE_STILL_TOLERANCE,
    base_is_still,
    path_length,
    segment_deltas,
    state_steps,
    wrap_angle,
)


def test_wrap_angle_lands_in_half_open_range() -> None:
    angles = np.random.default_rng(3).uniform(-20.0, 20.0, 500)
    wrapped = wrap_angle(np.concatenate([angles, [np.pi, -np.pi, -1e-17]]))
    assert np.all(wrapped >= -np.pi) and np.all(wrapped < np.pi)
    assert np.allclose(np.sin(wrapped[:500]), np.sin(angles))


def test_differences_take_the_short_way_for_the_heading_only() -> None:
    a = np.array([[0.0, 0.0, 3.0, 3.0]])
    b = np.array([[1.0, 0.0, -3.0, -3.0]])
    assert state_steps(a, b, base=BaseType.PLANAR)[0] == pytest.approx(
        [1.0, 0.0, 2 * np.pi - 6.0, -6.0]
    )
    assert state_steps(a, b, base=BaseType.FIXED)[0] == pytest.approx([1.0, 0.0, -6.0, -6.0])
    states = np.vstack([a, b, a])
    assert segment_deltas(states, base=BaseType.PLANAR).shape == (2, 4)
    expected = 2 * np.linalg.norm([1.0, 0.0, 2 * np.pi - 6.0, -6.0])
    assert path_length(states, base=BaseType.PLANAR) == pytest.approx(expected)
    assert path_length(states[:1], base=BaseType.PLANAR) == 0.0


def test_base_is_still_uses_the_strict_tolerance() -> None:
    start = np.array([1.0, 2.0, np.pi - 1e-12, 0.3])
    goal = np.array([1.0, 2.0, -np.pi, 0.9])  # the same heading, one turn apart
    assert base_is_still(start, goal, BaseType.PLANAR)
    nudged = goal + np.array([0.0, 2 * BASE_STILL_TOLERANCE, 0.0, 0.0])
    assert not base_is_still(start, nudged, BaseType.PLANAR)
    assert not base_is_still(start, start, BaseType.FIXED)
