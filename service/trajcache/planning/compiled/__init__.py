"""The compiled planner's kernels: RRT-Connect and simplification on sphere covers (numba)."""

from __future__ import annotations

from trajcache.geometry import kernel_cache  # noqa: F401  (first: its locators stamp the kernels)
