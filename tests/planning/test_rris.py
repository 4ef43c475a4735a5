"""RRIS on small seeded 2-D problems (a wall with a gap), and the Deadline it runs against."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import pytest

from tests.waiting import NEVER_BINDS_S, FakeClock
from trajcache.planning.deadline import Deadline
from trajcache.planning.rris import RrisGeometry, RrisOptions, plan_rris

STEP = 0.02  # sampling step of the 2-D segment checks
LOW, HIGH = np.zeros(2), np.full(2, 10.0)


def wall_world(gap: bool) -> Callable[[np.ndarray], np.ndarray]:
    """Collision test for points (N, 2): a wall at x ∈ [4.5, 5.5], open at y ∈ [4.5, 5.5]."""

    def colliding(points: np.ndarray) -> np.ndarray:
        x, y = points[:, 0], points[:, 1]
        in_wall = (x >= 4.5) & (x <= 5.5)
        if gap:
            in_wall &= (y < 4.5) | (y > 5.5)
        return in_wall | np.any((points < LOW) | (points > HIGH), axis=1)

    return colliding


def samples(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Points of a → b every STEP, a excluded, b included."""
    n = max(1, int(np.ceil(np.linalg.norm(b - a) / STEP)))
    t = np.arange(1, n + 1) / n
    return a + t[:, None] * (b - a)


class Geometry:
    """The callables RRIS takes, counting how often the segment checks ran."""

    def __init__(self, gap: bool = True) -> None:
        self.colliding = wall_world(gap)
        self.segment_calls = 0

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        self.segment_calls += 1
        return not self.colliding(samples(a, b)).any()

    def segment_collisions(self, a: np.ndarray, b: np.ndarray) -> int:
        self.segment_calls += 1
        return int(self.colliding(samples(a, b)).sum())

    @staticmethod
    def sample(rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(LOW, HIGH)


def plan(
    geometry: Geometry,
    seed: int,
    budget_s: float = NEVER_BINDS_S,
    clock: FakeClock | None = None,
    **kw: object,
) -> list | None:
    option_names = set(RrisOptions.__dataclass_fields__)
    return plan_rris(
        np.array([1.0, 1.0]),
        np.array([9.0, 1.0]),
        RrisGeometry(
            segment_free_fn=geometry.segment_free,
            segment_collisions_fn=geometry.segment_collisions,
            sample_fn=geometry.sample,
            **{k: v for k, v in kw.items() if k not in option_names},  # type: ignore[arg-type]
        ),
        budget=Deadline(budget_s) if clock is None else Deadline(budget_s, clock=clock),
        rng=np.random.default_rng(seed),
        options=RrisOptions(**{k: v for k, v in kw.items() if k in option_names}),  # type: ignore[arg-type]
    )


class TickingClock(FakeClock):
    """A fake clock that moves `step_s` forward each time it is read."""

    def __init__(self, step_s: float) -> None:
        super().__init__()
        self.step_s = step_s

    def __call__(self) -> float:
        self.now += self.step_s
        return self.now


def assert_valid_path(path: list, colliding: Callable[[np.ndarray], np.ndarray]) -> None:
    assert np.allclose(path[0], [1.0, 1.0]) and np.allclose(path[-1], [9.0, 1.0])
    for a, b in itertools.pairwise(path):
        dense = np.linspace(a, b, 2000)  # much finer than the planner's checks
        assert not colliding(dense).any(), f"segment {a} → {b} collides"


def test_free_straight_segment_is_returned_as_is() -> None:
    geometry = Geometry()
    start, goal = np.array([1.0, 1.0]), np.array([1.0, 9.0])
    path = plan_rris(
        start,
        goal,
        RrisGeometry(
            segment_free_fn=geometry.segment_free,
            segment_collisions_fn=geometry.segment_collisions,
            sample_fn=geometry.sample,
        ),
        budget=Deadline(1.0),
        rng=np.random.default_rng(0),
    )
    assert path is not None and len(path) == 2
    assert geometry.segment_calls == 1


@pytest.mark.parametrize("seed", range(5))
def test_finds_the_gap_in_the_wall(seed: int) -> None:
    geometry = Geometry(gap=True)
    path = plan(geometry, seed)
    assert path is not None
    assert len(path) >= 3  # the straight segment crosses the wall
    assert_valid_path(path, geometry.colliding)


def test_batched_callables_give_valid_paths_too() -> None:
    geometry = Geometry(gap=True)

    def states_free(states: np.ndarray) -> np.ndarray:
        return ~geometry.colliding(np.asarray(states))

    def segments_collisions(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        pairs = zip(starts, ends, strict=True)
        return np.array([geometry.segment_collisions(a, b) for a, b in pairs])

    path = plan(geometry, 3, states_free_fn=states_free, segments_collisions_fn=segments_collisions)
    assert path is not None
    assert_valid_path(path, geometry.colliding)


def test_same_seed_same_path() -> None:
    first = plan(Geometry(), 11)
    second = plan(Geometry(), 11)
    assert first is not None and second is not None
    assert len(first) == len(second)
    assert all(np.allclose(a, b) for a, b in zip(first, second, strict=True))


def test_impossible_problem_fails_within_the_budget() -> None:
    geometry = Geometry(gap=False)
    clock = TickingClock(step_s=0.001)  # every look at the budget costs a millisecond
    path = plan(geometry, 0, budget_s=0.3, clock=clock)
    assert path is None
    assert 0.3 <= clock.now < 0.3 + 0.02  # it stopped soon after the budget was spent
    assert geometry.segment_calls > 10  # it did search, with restarts


def test_depth_limit_bounds_a_single_attempt() -> None:
    geometry = Geometry(gap=True)
    path = plan(geometry, 0, restarts=1, max_depth=0)
    assert path is None
    assert geometry.segment_calls == 1  # only the straight check: depth 0 allows no split


def test_deadline_counts_down_and_nests() -> None:
    clock = FakeClock(100.0)
    deadline = Deadline(0.2, clock=clock)
    assert not deadline.expired() and deadline.remaining() == pytest.approx(0.2)
    child = deadline.sub(10.0)
    assert child.ends == pytest.approx(deadline.ends)  # never outlives its parent
    assert deadline.sub(0.05).ends == pytest.approx(100.05)
    clock.advance(0.15)
    assert deadline.elapsed() == pytest.approx(0.15)
    assert child.remaining() == pytest.approx(0.05) and not child.expired()
    clock.advance(0.05)
    assert deadline.expired() and child.expired() and deadline.remaining() == 0.0
    assert Deadline(0.0).expired() and Deadline(0.0).remaining() == 0.0
    assert Deadline(-1.0).remaining() == 0.0
