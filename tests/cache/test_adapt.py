"""Adapting a cached trajectory to a request: endpoints, re-anchoring, reversal, heading wrap."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.cache.adapt import adapt_trajectory
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.space import base_is_still


def trajectory(rng: np.random.Generator, n: int = 6, dim: int = 6) -> np.ndarray:
    states = rng.uniform(-1, 1, (n, dim))
    states[:, :2] *= 3
    return states


def test_endpoints_replaced_and_interior_kept_when_base_moves() -> None:
    rng = np.random.default_rng(0)
    states = trajectory(rng)
    start, goal = states[0] + 0.05, states[-1] - 0.05
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
    np.testing.assert_array_equal(out[0], start)
    np.testing.assert_array_equal(out[-1], goal)
    np.testing.assert_array_equal(out[1:-1], states[1:-1])


def test_still_base_reanchors_every_intermediate_pose() -> None:
    rng = np.random.default_rng(1)
    states = trajectory(rng)
    start = np.array([2.0, -1.0, 0.4, 0.1, 0.2, 0.3])
    goal = np.array([2.0, -1.0, 0.4, -0.1, -0.2, -0.3])
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
    np.testing.assert_array_equal(out[:, :3], np.tile(start[:3], (len(states), 1)))
    np.testing.assert_array_equal(out[1:-1, 3:], states[1:-1, 3:])  # arm motion untouched
    np.testing.assert_array_equal(out[0], start)
    np.testing.assert_array_equal(out[-1], goal)


def test_base_moving_by_more_than_tolerance_is_not_reanchored() -> None:
    rng = np.random.default_rng(2)
    states = trajectory(rng)
    start = np.array([2.0, -1.0, 0.4, 0.1, 0.2, 0.3])
    goal = start + np.array([1e-6, 0, 0, 0, 0, 0])
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
    np.testing.assert_array_equal(out[1:-1], states[1:-1])


def test_base_is_still_wraps_heading_and_ignores_fixed_base() -> None:
    s = np.array([1.0, 1.0, np.pi - 1e-12, 0.0])
    g = np.array([1.0, 1.0, -np.pi + 1e-12, 1.0])
    assert base_is_still(s, g, BaseType.PLANAR)
    assert not base_is_still(s, g + np.array([0, 2e-9, 0, 0]), BaseType.PLANAR)
    assert not base_is_still(np.zeros(3), np.zeros(3), BaseType.FIXED)


def test_reverse_plays_the_cached_path_backwards() -> None:
    rng = np.random.default_rng(3)
    states = trajectory(rng)
    start, goal = states[-1], states[0]
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR, reverse=True)
    np.testing.assert_array_equal(out, states[::-1])


def test_input_is_never_mutated_and_output_is_new() -> None:
    rng = np.random.default_rng(4)
    states = trajectory(rng)
    before = states.copy()
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    out = adapt_trajectory(states, start, start, base=BaseType.PLANAR, reverse=True)
    np.testing.assert_array_equal(states, before)
    assert not np.shares_memory(out, states)
    out2 = adapt_trajectory(states, start, start + 1, base=BaseType.PLANAR)
    assert not np.shares_memory(out2, states)


def test_two_states_are_just_start_and_goal() -> None:
    states = np.zeros((2, 5))
    start, goal = np.full(5, 0.1), np.full(5, 0.2)
    out = adapt_trajectory(states, start, goal, base=BaseType.FIXED)
    np.testing.assert_array_equal(out, [start, goal])
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
    np.testing.assert_array_equal(out, [start, goal])


def test_endpoint_heading_unwrapped_towards_neighbour() -> None:
    states = np.zeros((4, 4))
    states[:, 2] = [3.0, 3.1, 3.2, 3.3]  # a continuous path past +π
    start = np.array([0.0, 0.0, 3.05, 0.0])
    goal = np.array([1.0, 0.0, 3.3 - 2 * np.pi, 0.0])  # the same heading, wrapped
    out = adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
    assert out[0, 2] == start[2]  # already continuous: untouched
    assert out[-1, 2] == pytest.approx(3.3)
    assert np.all(np.abs(np.diff(out[:, 2])) < np.pi)


def test_two_state_heading_unwrapped_towards_start() -> None:
    start = np.array([0.0, 0.0, 3.1, 0.5])
    goal = np.array([1.0, 0.0, -3.1, 0.5])
    out = adapt_trajectory(np.zeros((2, 4)), start, goal, base=BaseType.PLANAR)
    np.testing.assert_array_equal(out[0], start)
    assert out[1, 2] == pytest.approx(2 * np.pi - 3.1)


def test_fixed_base_joints_are_not_unwrapped() -> None:
    states = np.zeros((3, 3))
    start, goal = np.array([3.0, 3.0, 3.0]), np.array([-3.0, -3.0, -3.0])
    out = adapt_trajectory(states, start, goal, base=BaseType.FIXED)
    np.testing.assert_array_equal(out[[0, -1]], [start, goal])


@pytest.mark.parametrize(
    ("states", "start", "goal"),
    [
        (np.zeros((1, 4)), np.zeros(4), np.zeros(4)),
        (np.zeros((3, 4)), np.zeros(3), np.zeros(4)),
        (np.zeros(4), np.zeros(4), np.zeros(4)),
    ],
)
def test_rejects_bad_shapes(states: np.ndarray, start: np.ndarray, goal: np.ndarray) -> None:
    with pytest.raises(ValueError):
        adapt_trajectory(states, start, goal, base=BaseType.PLANAR)
