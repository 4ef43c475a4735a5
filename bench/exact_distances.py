"""The exact level's convex distances: the compiled GJK against coal, on random pairs.

Pairs of every shape kind the service knows (box, sphere, cylinder, capsule, a convex mesh and
a concave one, a U of three boxes, bounded as its hull), posed at random within 0.35 m of each
other, seeded. Per pair:

- coal's distance between the two as convex shapes (meshes as coal's convex hulls), called from
  Python as the service called it before (`coal.distance` with fresh transforms per pair);
- the compiled GJK's lower bound (`geometry/collision/compiled/gjk.py`), run to the end (no
  need), in one call over every pair;
- the same with a need of half the distance, where the search may stop early.

Reports the time per pair of each, and the bound against coal's distance: how far above it the
bound ever is (a proved bound is never above the true distance; coal's own answer is within its
tolerance, 1e-6 m, of it) and how far below at most and at the 99th percentile. The last line is
one JSON object. Exits 1 when a bound is above coal's distance by more than coal's tolerance.

    python bench/exact_distances.py [--smoke] [--pairs N] [--seed N]
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import coal
import numpy as np
import trimesh
from rich.console import Console
from rich.table import Table

from trajcache.geometry.collision.compiled.gjk import convex_lower_rows
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind, pose_matrix
from trajcache.geometry.model.support import SupportTable

KINDS = ("box", "sphere", "cylinder", "capsule", "convex mesh", "concave mesh")
COAL_TOLERANCE = 1e-6


def shape(rng: np.random.Generator, kind: str) -> Shape:
    """A random shape of `kind`, a few centimetres to 30 cm across."""
    if kind == "box":
        return Shape(ShapeKind.BOX, tuple(rng.uniform(0.02, 0.3, 3)))
    if kind == "sphere":
        return Shape(ShapeKind.SPHERE, (rng.uniform(0.01, 0.2),))
    if kind in ("cylinder", "capsule"):
        return Shape(ShapeKind(kind), tuple(rng.uniform(0.01, 0.3, 2)))
    if kind == "convex mesh":
        mesh = trimesh.creation.icosphere(1, radius=rng.uniform(0.05, 0.2))
        vertices = mesh.vertices * rng.uniform(0.5, 1.5, 3) + rng.uniform(-0.05, 0.05, 3)
    else:
        size = rng.uniform(0.05, 0.2)
        mesh = trimesh.util.concatenate(
            [
                trimesh.creation.box((size, size / 4, size / 4), _moved(0, -size * 3 / 8)),
                trimesh.creation.box((size / 4, size, size / 4), _moved(-size * 3 / 8, 0)),
                trimesh.creation.box((size, size / 4, size / 4), _moved(0, size * 3 / 8)),
            ]
        )
        vertices = mesh.vertices
    return Shape(ShapeKind.MESH, vertices=np.asarray(vertices), faces=np.asarray(mesh.faces))


def _moved(x: float, y: float) -> FloatArray:
    pose = np.eye(4)
    pose[:2, 3] = (x, y)
    return pose


def poses(rng: np.random.Generator, count: int) -> FloatArray:
    """Random poses within 0.35 m of the origin, uniformly random orientations."""
    quats = rng.normal(size=(count, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    return np.array([pose_matrix(rng.uniform(-0.35, 0.35, 3), q) for q in quats])


def coal_distances(pairs: Pairs) -> tuple[FloatArray, float]:
    """coal's distance of each pair as convex shapes, called per pair from Python; µs a pair."""
    hulls, index_a, index_b, poses_a, poses_b = pairs[0], pairs[2], pairs[3], pairs[4], pairs[5]
    count = len(index_a)
    out = np.empty(count)
    request = coal.DistanceRequest()
    began = time.perf_counter()
    for k in range(count):
        a, b = poses_a[k], poses_b[k]
        out[k] = coal.distance(
            hulls[index_a[k]], coal.Transform3s(a[:3, :3], a[:3, 3]),
            hulls[index_b[k]], coal.Transform3s(b[:3, :3], b[:3, 3]),
            request, coal.DistanceResult(),
        )  # fmt: skip
    return out, (time.perf_counter() - began) / count * 1e6


def gjk_bounds(pairs: Pairs, need: FloatArray) -> tuple[FloatArray, float]:
    """The compiled GJK's bound of each pair, in one call (timed after a first, untimed one,
    which compiles or loads the kernel); µs a pair."""
    table, index_a, index_b, poses_a, poses_b = pairs[1], pairs[2], pairs[3], pairs[4], pairs[5]
    out = np.empty(len(index_a))
    sup = table.kernel_args
    call = (poses_a, sup, index_a, poses_b, sup, index_b, need, np.empty((4, 3)), out)
    convex_lower_rows(*call)
    began = time.perf_counter()
    convex_lower_rows(*call)
    return out, (time.perf_counter() - began) / len(index_a) * 1e6


Pairs = tuple[
    list[coal.CollisionGeometry], SupportTable, np.ndarray, np.ndarray, FloatArray, FloatArray
]


def random_pairs(count: int, seed: int) -> Pairs:
    """Shapes of every kind as coal hulls and a support table, and `count` posed pairs of them."""
    rng = np.random.default_rng(seed)
    shapes = [shape(rng, KINDS[k % len(KINDS)]) for k in range(12 * len(KINDS))]
    hulls = [s.to_coal_hull(s.to_coal()) for s in shapes]
    index_a, index_b = rng.integers(len(shapes), size=(2, count))
    return hulls, SupportTable.build(shapes), index_a, index_b, poses(rng, count), poses(rng, count)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--smoke", action="store_true", help="2,000 pairs")
    args = parser.parse_args(argv)
    count = 2_000 if args.smoke else args.pairs
    pairs = random_pairs(count, args.seed)
    truth, coal_us = coal_distances(pairs)
    full, full_us = gjk_bounds(pairs, np.full(count, np.inf))
    early, early_us = gjk_bounds(pairs, np.where(truth > 0.0, truth / 2.0, np.inf))
    apart = truth > COAL_TOLERANCE
    below = (truth - full)[apart]
    above = float(np.max(np.minimum(full, early) - np.maximum(truth, 0.0)))
    most, p99 = float(np.max(below)), float(np.quantile(below, 0.99))
    out = Table(title=f"Exact convex distances, {count} random pairs ({int(apart.sum())} apart)")
    out.add_column("")
    out.add_column("µs per pair", justify="right")
    out.add_row("coal, from Python (hulls)", f"{coal_us:.2f}")
    out.add_row("compiled GJK, to the end", f"{full_us:.2f}")
    out.add_row("compiled GJK, need = half the distance", f"{early_us:.2f}")
    Console().print(out)
    print(f"bound - coal: at most {above:.2e} m above; at most {most:.2e} m below (p99 {p99:.2e})")
    overlaps = int(np.sum(full[~apart] > COAL_TOLERANCE))
    print(
        json.dumps(
            {
                "pairs": count,
                "apart": int(apart.sum()),
                "coal_us_per_pair": round(coal_us, 3),
                "gjk_us_per_pair": round(full_us, 3),
                "gjk_need_half_us_per_pair": round(early_us, 3),
                "speedup": round(coal_us / full_us, 1),
                "most_above_coal_m": above,
                "most_below_coal_m": most,
                "p99_below_coal_m": p99,
                "overlaps_bounded_positive": overlaps,
            }
        )
    )
    return 0 if above <= COAL_TOLERANCE and overlaps == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
