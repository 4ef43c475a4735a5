"""Warming: compile (or load from numba's cache) every kernel before a request needs it: the
geometry's (`geometry/warm.py`) and the compiled planner's.

The service calls `warm()` when it starts, the Celery worker before it forks its processes, and
`make setup` once to fill numba's on-disk cache. The planner pool's forkserver imports
`trajcache.jobs.preload`, which calls it.
"""

from __future__ import annotations

import numpy as np

from trajcache.geometry.warm import warm as warm_geometry
from trajcache.geometry.warm import warm_problem
from trajcache.planning.compiled_planner import warm_compiled


def warm() -> None:
    """Every kernel, through the code that calls them."""
    warm_geometry()
    model, scene = warm_problem()
    warm_compiled(model, scene, np.array([-1.5, 0.0]), np.array([1.5, 0.1]))
