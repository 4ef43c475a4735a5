"""The planner names a request or a setting may ask for (the planners live in `planning/`).

Here, below `planning/`, so that the settings can check a name without importing a planner.
"""

from __future__ import annotations

__all__ = ["PLANNER_NAMES"]

# The paper's RRIS, the OMPL planners of `planning.ompl_planner` and the compiled RRT-Connect of
# `planning.compiled_planner`.
PLANNER_NAMES = ("rrtconnect", "rrt", "bitstar", "bit*", "prm", "kpiece", "rris", "compiled")
