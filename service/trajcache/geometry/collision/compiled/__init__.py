"""The certification levels compiled: every segment, pair and cover ball in one call per batch.

`validation/certify.py` settles pairs level by level in numpy (element balls, support-function
slabs, the sphere covers and the slabs they suggest); the same levels, with the same bounds, run
here as numba kernels with no Python per segment, pair or ball. What they leave open, the few pairs
no level settles, goes on to the same FCL-directed slab and conservative advancement as before.

Per segment k (samples a, b) and pair, with lower bounds d_a, d_b at the ends and a bound M on
how far any point of the pair moves relative to the other over the segment, d_a + d_b > M
certifies the pair on the segment (`validation/certify.py`). The levels, cheapest first:

1. the element's ball around its origin, the motion of that origin (configuration-independent
   coefficients; `model/motion.py`);
2. slabs along the box's and the element's face normals and toward the nearest box point (for a
   robot pair: the line between the elements, across both their z axes, both elements' face
   normals), meshes first as their bounding boxes, then as their hulls along the three best of
   those directions; the motion of the whole element, first configuration-independent, then
   from the axis distances at both ends;
3. every ball of the element's sphere cover with the motion of its own centre; when a ball is
   not settled, slabs along the ways the four closest balls look to the box (for a pair,
   between the four closest pairs of balls) with the whole element's motion.

Scene objects whose bounding box the element cannot reach within the segment (its ball grown by
its whole motion, from both ends) are settled by that alone.

Modules: `slabs.py` (support functions and slabs), `primitives.py` (poses, world boxes, motion
bounds), `scene_open.py` and `self_open.py` (the segment kernels), `state_rows.py` (single
states). Forward kinematics and the hull climb are the model's (`model/kernels.py`). Their
on-disk cache is stamped with every kernel source file (`geometry/kernel_cache.py`).
"""

from __future__ import annotations

from trajcache.geometry import kernel_cache  # noqa: F401  (first: its locators stamp the kernels)
from trajcache.geometry.collision.compiled.scene_open import scene_open_kernel
from trajcache.geometry.collision.compiled.self_open import self_open_kernel
from trajcache.geometry.collision.compiled.state_rows import state_rows_kernel

__all__ = ["scene_open_kernel", "self_open_kernel", "state_rows_kernel"]
