"""TrajectoryIndex against a brute-force scan with the paper's metric."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from trajcache.cache.index import _FEW, Match, TrajectoryIndex
from trajcache.cache.metric import state_distance
from trajcache.geometry.model.robot import BaseType

D = 6  # planar base + 3 joints
Expected = list[tuple[int, bool, float]]


def brute_force(
    ids: np.ndarray,
    starts: np.ndarray,
    goals: np.ndarray,
    start: np.ndarray,
    goal: np.ndarray,
    *,
    base: BaseType = BaseType.PLANAR,
    threshold: float = 0.2,
    arm_only: bool = False,
    goal_threshold: float | None = None,
) -> Expected:
    """All relevant (id, reversed, score), best orientation per id, sorted by (score, id); with
    `goal_threshold`, each end within it and the start's summed distance within `threshold`."""
    best: dict[int, tuple[float, bool]] = {}
    wide = goal_threshold or threshold
    for rev, (first, second) in enumerate(((starts, goals), (goals, starts))):
        b1, a1 = state_distance(first, start, base=base)
        b2, a2 = state_distance(second, goal, base=base)
        if arm_only:
            b1, b2 = 0 * b1, 0 * b2
        ok = (b1 < wide) & (a1 < wide) & (b2 < wide) & (a2 < wide)
        if goal_threshold is not None:
            ok &= b1 + a1 < threshold
        for i in np.flatnonzero(ok):
            score = float(b1[i] + a1[i] + b2[i] + a2[i])
            key = int(ids[i])
            if key not in best or (score, rev) < (best[key][0], best[key][1]):
                best[key] = (score, bool(rev))
    rows = [(i, r, s) for i, (s, r) in best.items()]
    return sorted(rows, key=lambda row: (row[2], row[0]))


def as_rows(matches: list[Match]) -> Expected:
    return [(m.trajectory_id, m.reversed, m.score) for m in matches]


def assert_same(got: list[Match], want: Expected) -> None:
    assert [(i, r) for i, r, _ in as_rows(got)] == [(i, r) for i, r, _ in want]
    np.testing.assert_allclose([s for *_, s in as_rows(got)], [s for *_, s in want], atol=1e-12)


def clustered(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Starts/goals around a few anchors, headings near ±π, some reversed duplicates."""
    anchors = np.c_[
        rng.uniform(0, 1, (6, 2)), rng.choice([np.pi - 0.03, -np.pi + 0.03, 0.0], 6),
        rng.uniform(-1, 1, (6, 3)),
    ]  # fmt: skip
    a = anchors[rng.integers(0, 6, n)] + rng.uniform(-0.1, 0.1, (n, D))
    b = anchors[rng.integers(0, 6, n)] + rng.uniform(-0.1, 0.1, (n, D))
    a[:, 2] = np.mod(a[:, 2] + np.pi, 2 * np.pi) - np.pi
    return a, b  # goal headings deliberately left unwrapped (> π possible)


def queries(rng: np.random.Generator, starts: np.ndarray, goals: np.ndarray, k: int) -> list:
    pick = rng.integers(0, len(starts), k)
    swap = rng.random(k) < 0.3
    qs = np.where(swap[:, None], goals[pick], starts[pick]) + rng.uniform(-0.1, 0.1, (k, D))
    qg = np.where(swap[:, None], starts[pick], goals[pick]) + rng.uniform(-0.1, 0.1, (k, D))
    return list(zip(qs, qg, strict=True))


@pytest.mark.parametrize("arm_only", [False, True])
def test_matches_brute_force_main_and_delta(arm_only: bool) -> None:
    rng = np.random.default_rng(0)
    starts, goals = clustered(rng, 3000)
    ids = rng.permutation(10_000)[:3000]
    index = TrajectoryIndex(D, base=BaseType.PLANAR, rebuild_min=100_000, background_rebuild=False)
    index.add(ids[:2000], starts[:2000], goals[:2000])
    index.rebuild()
    index.add(ids[2000:], starts[2000:], goals[2000:])  # stays in the delta
    assert index.delta_size == 1000 and len(index) == 3000
    counts = []
    for s, g in queries(rng, starts, goals, 60):
        want = brute_force(ids, starts, goals, s, g, arm_only=arm_only)
        assert_same(index.query(s, g, limit=10**6, arm_only=arm_only), want)
        assert_same(index.query(s, g, limit=3, arm_only=arm_only), want[:3])
        counts.append(len(want))
    assert sum(counts) > 60  # the test data must actually produce matches
    assert min(counts) <= _FEW < max(counts)  # ranked both ways: in Python and by numpy


@pytest.mark.parametrize("base", [BaseType.PLANAR, BaseType.FIXED])
def test_a_wider_goal_threshold_keeps_the_start_s(base: BaseType) -> None:
    """A pose goal's lookup: goal ends up to 0.6 away, start ends within 0.2 (main and delta,
    both orientations), as a brute-force scan finds them."""
    rng = np.random.default_rng(3)
    starts, goals = clustered(rng, 1500)
    ids = np.arange(1500)
    index = TrajectoryIndex(D, base=base, rebuild_min=100_000, background_rebuild=False)
    index.add(ids[:1000], starts[:1000], goals[:1000])
    index.rebuild()
    index.add(ids[1000:], starts[1000:], goals[1000:])
    widened = 0
    for s, g in queries(rng, starts, goals, 40):
        g = g + rng.uniform(-0.4, 0.4, D)
        want = brute_force(ids, starts, goals, s, g, base=base, goal_threshold=0.6)
        assert_same(index.query(s, g, limit=10**6, goal_threshold=0.6), want)
        assert_same(index.query(s, g, limit=2, goal_threshold=0.6), want[:2])
        narrow = brute_force(ids, starts, goals, s, g, base=base)
        assert_same(index.query(s, g, limit=10**6, goal_threshold=0.1), narrow)
        widened += len(want) - len(narrow)
    assert widened > 40  # the wider threshold finds more


def test_removals_and_rebuild_keep_results_exact() -> None:
    rng = np.random.default_rng(1)
    starts, goals = clustered(rng, 2000)
    ids = np.arange(2000) * 3
    index = TrajectoryIndex(D, base=BaseType.PLANAR, rebuild_min=256, background_rebuild=False)
    for lo in range(0, 2000, 250):  # crosses several automatic rebuilds
        index.add(ids[lo : lo + 250], starts[lo : lo + 250], goals[lo : lo + 250])
    gone = rng.choice(ids, 700, replace=False)
    index.remove(np.r_[gone, 1, 2])  # unknown ids are ignored
    keep = ~np.isin(ids, gone)
    assert len(index) == keep.sum()
    np.testing.assert_array_equal(index.ids(), ids[keep])
    assert int(gone[0]) not in index and int(ids[keep][0]) in index
    qs = queries(rng, starts, goals, 40)
    for rebuilt in (False, True):
        if rebuilt:
            index.rebuild()
            assert index.delta_size == 0
        for s, g in qs:
            want = brute_force(ids[keep], starts[keep], goals[keep], s, g)
            assert_same(index.query(s, g, limit=50), want[:50])


@pytest.mark.parametrize("in_delta", [False, True])
@pytest.mark.parametrize(
    ("offset", "relevant"),
    [
        ({3: 0.19}, True),  # arm joint
        ({3: 0.21}, False),
        ({0: 0.19}, True),  # base x
        ({0: 0.21}, False),
        ({0: 0.12, 1: 0.16}, False),  # |Δp| = 0.2 is not below 0.2
        ({0: 0.09, 2: 0.1}, True),  # 0.09 + 0.1
        ({0: 0.1, 2: 0.11}, False),  # 0.1 + 0.11
    ],
)
def test_threshold_boundary(offset: dict[int, float], relevant: bool, in_delta: bool) -> None:
    start = np.array([1.0, 1.0, 0.5, 0.1, 0.2, 0.3])
    goal = np.array([2.0, 1.0, -0.5, 0.3, 0.2, 0.1])
    cached = goal.copy()
    for col, value in offset.items():
        cached[col] += value
    index = TrajectoryIndex(D, base=BaseType.PLANAR, background_rebuild=False)
    index.add([7], [start], [cached])
    if not in_delta:
        index.rebuild()
    matches = index.query(start, goal)
    assert [m.trajectory_id for m in matches] == ([7] if relevant else [])


@pytest.mark.parametrize("in_delta", [False, True])
def test_heading_wraps_around_pi(in_delta: bool) -> None:
    start = np.array([1.0, 1.0, np.pi - 0.05, 0.0, 0.0, 0.0])
    goal = np.array([1.0, 1.0, -np.pi + 0.02, 0.5, 0.0, 0.0])
    index = TrajectoryIndex(D, base=BaseType.PLANAR, background_rebuild=False)
    near = start.copy()
    near[2] = -np.pi + 0.05  # 0.1 away across the wrap
    far = start.copy()
    far[2] = -np.pi + 0.2  # 0.25 away across the wrap
    turn = np.array([0, 0, 2 * np.pi, 0, 0, 0])
    index.add([1, 2], [near, far], [goal + turn] * 2)
    if not in_delta:
        index.rebuild()
    (match,) = index.query(start, goal)
    assert match.trajectory_id == 1 and not match.reversed
    assert match.d_start == pytest.approx(0.1) and match.d_goal == pytest.approx(0.0, abs=1e-9)
    # the request may also be given with unwrapped headings
    assert index.query(start + 2 * turn, goal)[0].trajectory_id == 1


def test_reversed_match_reports_request_oriented_distances() -> None:
    a = np.array([0.0, 0.0, 0.0, 0.1, 0.1, 0.1])
    b = np.array([3.0, 2.0, 1.0, 1.0, 1.0, 1.0])
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    index.add([5], [a], [b])
    request_start = b + np.array([0.05, 0, 0, 0, 0, 0])
    (match,) = index.query(request_start, a)
    assert match == Match(5, True, pytest.approx(0.05), pytest.approx(0.0), pytest.approx(0.05))
    (fwd,) = index.query(a, b)
    assert not fwd.reversed and fwd.score == 0.0


def test_palindrome_prefers_forward_and_appears_once() -> None:
    a = np.array([0.0, 0.0, 0.0, 0.1, 0.1, 0.1])
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    index.add([9], [a], [a + 0.01])
    matches = index.query(a + 0.005, a + 0.005)
    assert len(matches) == 1 and not matches[0].reversed


def test_arm_only_ignores_base() -> None:
    start = np.array([0.0, 0.0, 0.0, 0.1, 0.2, 0.3])
    goal = np.array([0.0, 0.0, 0.0, 1.1, 0.2, -0.3])
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    moved = np.array([4.0, 3.0, 2.5, 0, 0, 0])  # learned at another station
    bent = np.array([0, 0, 0, 0.25, 0, 0])
    index.add([1, 2], [start + moved] * 2, [goal + moved, goal + moved + bent])
    assert index.query(start, goal) == []
    (match,) = index.query(start, goal, arm_only=True)
    assert match.trajectory_id == 1 and match.score == pytest.approx(0.0)
    index.rebuild()  # the arm-only tree survives a rebuild
    assert [m.trajectory_id for m in index.query(start, goal, arm_only=True)] == [1]


def test_fixed_base_layout() -> None:
    rng = np.random.default_rng(2)
    starts, goals = rng.uniform(-1, 1, (500, 4)), rng.uniform(-1, 1, (500, 4))
    ids = np.arange(500)
    index = TrajectoryIndex(4, base=BaseType.FIXED, rebuild_min=100, background_rebuild=False)
    index.add(ids, starts, goals)
    for i in range(0, 500, 25):
        s, g = starts[i] + 0.05, goals[i] - 0.05
        want = brute_force(ids, starts, goals, s, g, base=BaseType.FIXED)
        assert_same(index.query(s, g, limit=100), want)
        assert int(i) in {row[0] for row in want}
        assert index.query(s, g, arm_only=True) == index.query(s, g)


def test_limit_and_ties_by_id() -> None:
    a = np.array([0.0, 0.0, 0.0, 0.1, 0.1, 0.1])
    b = a + 1
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    index.add([30, 10, 20, 40], [a, a, a, a + 0.01], [b, b, b, b])
    assert [m.trajectory_id for m in index.query(a, b)] == [10, 20, 30]
    assert [m.trajectory_id for m in index.query(a, b, limit=5)] == [10, 20, 30, 40]
    assert index.query(a, b, limit=0) == []
    assert [m.trajectory_id for m in index.query(a, b, limit=1)] == [10]


def test_add_replaces_existing_id_and_clear() -> None:
    a = np.zeros(D)
    b = np.ones(D)
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    index.add([1], [a], [b])
    index.rebuild()
    index.add([1], [b], [a + 5])  # same id, new endpoints
    assert len(index) == 1 and index.query(a, b) == []
    assert [m.trajectory_id for m in index.query(b, a + 5)] == [1]
    index.clear()
    assert len(index) == 0 and 1 not in index and index.query(b, a + 5) == []


def test_rejects_bad_input() -> None:
    index = TrajectoryIndex(D, base=BaseType.PLANAR)
    with pytest.raises(ValueError):
        index.add([1, 2], np.zeros((2, D)), np.zeros((2, D + 1)))
    with pytest.raises(ValueError):
        index.add([1, 1], np.zeros((2, D)), np.zeros((2, D)))
    with pytest.raises(ValueError):
        index.add([1], np.full((1, D), np.nan), np.zeros((1, D)))
    with pytest.raises(ValueError):
        index.query(np.zeros(D), np.zeros(D), threshold=0)
    with pytest.raises(ValueError):
        TrajectoryIndex(2, base=BaseType.PLANAR)  # too short for x, y, θ
    assert len(index) == 0


def test_concurrent_mutations_and_queries_stay_consistent() -> None:
    rng = np.random.default_rng(3)
    starts, goals = clustered(rng, 6000)
    ids = np.arange(6000)
    index = TrajectoryIndex(D, base=BaseType.PLANAR, rebuild_min=200, background_rebuild=True)
    errors: list[BaseException] = []
    stop = threading.Event()
    qs = queries(rng, starts, goals, 50)

    def writer(lo: int, hi: int) -> None:
        try:
            for c in range(lo, hi, 50):
                index.add(ids[c : c + 50], starts[c : c + 50], goals[c : c + 50])
                index.remove(ids[c : c + 50 : 7])
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    def reader(seed: int) -> None:
        local = np.random.default_rng(seed)
        try:
            while not stop.is_set():
                for s, g in qs:
                    for m in index.query(s, g, limit=5, arm_only=bool(local.random() < 0.3)):
                        assert m.score < 0.8
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    readers = [threading.Thread(target=reader, args=(seed,)) for seed in range(3)]
    writers = [threading.Thread(target=writer, args=(lo, lo + 2000)) for lo in (0, 2000, 4000)]
    for t in readers + writers:
        t.start()
    for t in writers:
        t.join()
    stop.set()
    for t in readers:
        t.join()
    assert not errors
    keep = np.ones(6000, bool)
    for lo in range(0, 6000, 50):
        keep[lo : lo + 50 : 7] = False
    index.rebuild()
    np.testing.assert_array_equal(index.ids(), ids[keep])
    assert len(index) == keep.sum() and index.delta_size == 0
    for s, g in qs[:20]:
        want = brute_force(ids[keep], starts[keep], goals[keep], s, g)
        assert_same(index.query(s, g, limit=100), want[:100])


@pytest.mark.parametrize("base", [BaseType.PLANAR, BaseType.FIXED])
def test_ends_near_a_state_match_a_scan(base: BaseType) -> None:
    """Every entry with an end within the threshold of a state (main, delta, removed ones
    left out), with its other end, nearest first, as a brute-force scan of both ends finds."""
    rng = np.random.default_rng(4)
    starts, goals = clustered(rng, 1200)
    ids = np.arange(1200) * 7
    index = TrajectoryIndex(D, base=base, rebuild_min=100_000, background_rebuild=False)
    index.add(ids[:800], starts[:800], goals[:800])
    index.rebuild()
    index.add(ids[800:], starts[800:], goals[800:])
    index.remove(ids[::9])
    alive = ~np.isin(ids, ids[::9])
    found = 0
    for s, _ in queries(rng, starts, goals, 30):
        got = index.ends_near(s, threshold=0.2)
        want = []
        for end, (near, far) in enumerate(((starts, goals), (goals, starts))):
            b, a = state_distance(near, s, base=base)
            for i in np.flatnonzero((b < 0.2) & (a < 0.2) & alive):
                want.append((float(b[i] + a[i]), int(ids[i]), end, far[i]))
        want.sort(key=lambda w: w[:3])
        assert got.ids.tolist() == [w[1] for w in want]
        assert got.reversed.tolist() == [w[2] == 1 for w in want]
        np.testing.assert_allclose(got.distances, [w[0] for w in want], atol=1e-12)
        if want:
            b, a = state_distance(got.states, np.array([w[3] for w in want]), base=base)
            assert (b < 1e-9).all() and (a < 1e-9).all()  # the other end (θ modulo 2π)
        found += len(want)
    assert found > 30
