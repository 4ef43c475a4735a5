"""The share of a core that optional background work may take."""

from __future__ import annotations

import pytest

from trajcache.core.budget import WorkBudget


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_work_beyond_the_share_is_skipped_until_the_window_slides_on() -> None:
    clock = Clock()
    budget = WorkBudget(share=0.25, window_s=2.0, clock=clock)  # 0.5 s of work per 2 s
    ran: list[int] = []

    def work(k: int, seconds: float) -> None:
        ran.append(k)
        clock.now += seconds

    assert budget.spend(lambda: work(1, 0.3))
    assert budget.spend(lambda: work(2, 0.3))  # 0.3 s spent: still under 0.5
    assert not budget.spend(lambda: work(3, 0.1))  # 0.6 s spent within the window
    assert ran == [1, 2] and budget.skipped == 1
    clock.now += 1.75  # the first run (ended at 0.3) has left the window
    assert budget.spend(lambda: work(4, 0.1))
    assert ran == [1, 2, 4]


def test_work_that_raises_still_counts() -> None:
    clock = Clock()
    budget = WorkBudget(share=0.1, window_s=1.0, clock=clock)

    def failing() -> None:
        clock.now += 0.2
        raise RuntimeError("no")

    with pytest.raises(RuntimeError):
        budget.spend(failing)
    assert not budget.spend(lambda: None)
