"""Warming: compile (or load from numba's cache) every kernel before a request needs it: the
geometry's (`geometry/warm.py`) and the compiled planner's.

`warm_steps` lists the kernel groups so that a caller can say how far it got (`trajcache warm`
and `trajcache serve` show a progress bar or one line per group); `warm()` runs them all. The
service calls `warm()` when it starts, the Celery worker before it forks its processes, and
`make setup` (`trajcache warm`) once to fill numba's on-disk cache. The planner pool's
forkserver imports `trajcache.jobs.preload`, which calls it.
"""

from __future__ import annotations

import numpy as np

from trajcache.geometry.warm import WarmStep, warm_problem
from trajcache.geometry.warm import warm_steps as geometry_steps
from trajcache.planning.compiled_planner import warm_compiled

__all__ = ["WarmStep", "warm", "warm_steps"]


def warm_steps() -> list[WarmStep]:
    """Every kernel group, in order: the geometry's, then the compiled planner's."""
    return [*geometry_steps(), ("compiled planner", _warm_planner)]


def warm() -> None:
    """Every kernel, through the code that calls them."""
    for _, run in warm_steps():
        run()


def _warm_planner() -> None:
    model, scene = warm_problem()
    warm_compiled(model, scene, np.array([-1.5, 0.0]), np.array([1.5, 0.1]))
