"""The paper's state metric: angle wrapping, d_base and d_arm."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.cache.metric import state_distance, wrap_angle
from trajcache.geometry.model.robot import BaseType


def test_wrap_angle_range_and_values() -> None:
    a = np.array([0.0, np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 2 * np.pi, 1.0, -1e-20, 7.0])
    w = wrap_angle(a)
    assert w.shape == a.shape
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    np.testing.assert_allclose(w[:7], [0.0, -np.pi, -np.pi, -np.pi, -np.pi, 0.0, 1.0], atol=1e-12)
    assert w[7] == pytest.approx(0.0, abs=1e-15)
    assert w[8] == pytest.approx(7.0 - 2 * np.pi)


def test_wrap_angle_is_vectorized_over_any_shape() -> None:
    rng = np.random.default_rng(0)
    a = rng.uniform(-50, 50, (4, 5, 6))
    w = wrap_angle(a)
    assert w.shape == a.shape
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)


def test_planar_distance_by_hand() -> None:
    a = np.array([0.0, 0.0, 0.1, 0.5, -0.5])
    b = np.array([0.3, 0.4, -0.1, 0.4, -0.2])
    d_base, d_arm = state_distance(a, b, base=BaseType.PLANAR)
    assert float(d_base) == pytest.approx(0.5 + 0.2)
    assert float(d_arm) == pytest.approx(0.3)


def test_heading_difference_wraps() -> None:
    a = np.array([1.0, 2.0, np.pi - 0.05, 0.0])
    b = np.array([1.0, 2.0, -np.pi + 0.05, 0.0])
    d_base, d_arm = state_distance(a, b, base=BaseType.PLANAR)
    assert float(d_base) == pytest.approx(0.1)
    assert float(d_arm) == 0.0


def test_fixed_base_has_zero_base_distance() -> None:
    a = np.array([0.0, 1.0, 2.0])
    b = np.array([0.5, 0.8, 2.0])
    d_base, d_arm = state_distance(a, b, base=BaseType.FIXED)
    assert float(d_base) == 0.0
    assert float(d_arm) == pytest.approx(0.5)


def test_planar_base_without_arm() -> None:
    d_base, d_arm = state_distance([0, 0, 0], [3, 4, 0], base=BaseType.PLANAR)
    assert float(d_base) == pytest.approx(5.0)
    assert float(d_arm) == 0.0


def test_broadcasting_matches_rowwise() -> None:
    rng = np.random.default_rng(1)
    a = rng.uniform(-3, 3, (2, 7, 10))
    b = rng.uniform(-3, 3, 10)
    d_base, d_arm = state_distance(a, b, base=BaseType.PLANAR)
    assert d_base.shape == d_arm.shape == (2, 7)
    for i in range(2):
        for j in range(7):
            db, da = state_distance(a[i, j], b, base=BaseType.PLANAR)
            assert d_base[i, j] == pytest.approx(float(db))
            assert d_arm[i, j] == pytest.approx(float(da))
    # symmetric
    d_base2, d_arm2 = state_distance(b, a, base=BaseType.PLANAR)
    np.testing.assert_allclose(d_base2, d_base)
    np.testing.assert_allclose(d_arm2, d_arm)


def test_rejects_mismatched_shapes() -> None:
    with pytest.raises(ValueError):
        state_distance(np.zeros(5), np.zeros(4), base=BaseType.FIXED)
    with pytest.raises(ValueError):
        state_distance(np.zeros(2), np.zeros(2), base=BaseType.PLANAR)
