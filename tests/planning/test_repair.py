"""Repairing a path segment by segment, on small 2-D paths with scripted verdicts."""

from __future__ import annotations

import numpy as np

from trajcache.planning.deadline import Deadline
from trajcache.planning.repair import remembered, repair_path

PATH = [np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([2.0, 0.0]), np.array([3.0, 0.0])]


def crosses(a: np.ndarray, b: np.ndarray, x: float) -> bool:
    """Whether the segment a → b spans the vertical line at `x`."""
    return bool(min(a[0], b[0]) < x < max(a[0], b[0]))


def test_rejected_segments_are_replaced_by_their_detours_and_the_rest_kept() -> None:
    asked: list[tuple[float, float]] = []

    def detour(a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
        asked.append((a[0], b[0]))
        return [a, (a + b) / 2 + [0.0, 1.0], b]

    repair = repair_path(
        PATH,
        certify_fn=lambda a, b: not crosses(a, b, 1.5),
        detour_fn=detour,
        budget=Deadline(5.0),
    )
    assert asked == [(1.0, 2.0)]  # only the rejected segment
    assert repair.path is not None and (repair.repaired, repair.failed) == (1, 0)
    assert [p.tolist() for p in repair.path] == [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.5, 1.0],
        [2.0, 0.0],
        [3.0, 0.0],
    ]


def test_a_segment_without_a_detour_fails_the_repair() -> None:
    repair = repair_path(
        PATH,
        certify_fn=lambda a, b: not crosses(a, b, 2.5),
        detour_fn=lambda a, b: None,
        budget=Deadline(5.0),
    )
    assert repair.path is None and (repair.repaired, repair.failed) == (0, 1)


def test_a_spent_budget_stops_the_repair() -> None:
    repair = repair_path(
        PATH, certify_fn=lambda a, b: True, detour_fn=lambda a, b: None, budget=Deadline(0.0)
    )
    assert repair.path is None and repair.failed == 0


def test_remembered_checks_each_segment_once() -> None:
    calls: list[float] = []

    def check(a: np.ndarray, b: np.ndarray) -> bool:
        calls.append(a[0])
        return bool(a[0] < 1.0)

    certify = remembered(check)
    verdicts = [certify(PATH[i], PATH[i + 1]) for i in (0, 1, 0, 1)]
    assert verdicts == [True, False, True, False]  # a rejection is remembered too
    assert calls == [0.0, 1.0]
    assert certify(PATH[1], PATH[0]) is False and calls == [0.0, 1.0, 1.0]  # another segment
