"""Importing this module compiles, or loads from numba's cache, every geometry kernel.

The planner pool's forkserver imports it before it forks any worker, so that every worker starts
with the kernels ready instead of loading them on its first plan.
"""

from trajcache.planning.warm import warm

warm()
