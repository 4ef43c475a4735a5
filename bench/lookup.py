"""Lookup latency of TrajectoryIndex from 10³ to 10⁶ cached trajectories.

States are 10-D (planar base + 7 joints). The workload: 300 base stations in a 6×4 m room and 300
arm task configurations; 2000 "poses" (station, task) and 20 000 "routes" (pose → pose, 30 % of them
keeping the base still); each trajectory is a route with ±0.05 uniform noise on every coordinate,
and 20 % of trajectories are uniform random states. At each size the index holds a delta buffer of
recent inserts near its rebuild limit (the slow case). Queries: half are perturbed copies (±0.03) of
cached entries, a quarter of those reversed (they hit); half are fresh draws from the workload (they
may hit). A second set of arm-only queries uses the arm-only tree. Memory is the sum of the
index's array ``nbytes`` plus tree nodes (72 B each), cross-checked by the process RSS growth. The
last line printed is one JSON object.

    python bench/lookup.py            # 10³ … 10⁶
    python bench/lookup.py --smoke    # 10³ … 10⁴, seconds
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass

import numpy as np

from trajcache.cache.index import TrajectoryIndex
from trajcache.cache.metric import state_distance, wrap_angle
from trajcache.geometry.model.robot import BaseType

DIM, BASE = 10, BaseType.PLANAR
LOW = np.r_[0.0, 0.0, -np.pi, np.full(7, -2.8)]
HIGH = np.r_[6.0, 4.0, np.pi, np.full(7, 2.8)]
THRESHOLD, LIMIT = 0.2, 3


@dataclass
class Workload:
    """A clustered generator of (start, goal) pairs."""

    rng: np.random.Generator

    def __post_init__(self) -> None:
        rng = self.rng
        stations = rng.uniform(LOW[:3], HIGH[:3], (300, 3))
        tasks = rng.uniform(LOW[3:], HIGH[3:], (300, 7))
        self.poses = np.c_[stations[rng.integers(0, 300, 2000)], tasks[rng.integers(0, 300, 2000)]]
        self.routes = rng.integers(0, 2000, (20_000, 2))
        self.still = rng.random(20_000) < 0.3

    def draw(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` (start, goal) pairs."""
        rng = self.rng
        pick = rng.integers(0, len(self.routes), n)
        starts = self.poses[self.routes[pick, 0]] + rng.uniform(-0.05, 0.05, (n, DIM))
        goals = self.poses[self.routes[pick, 1]] + rng.uniform(-0.05, 0.05, (n, DIM))
        goals[self.still[pick], :3] = starts[self.still[pick], :3]
        uniform = rng.random(n) < 0.2
        starts[uniform] = rng.uniform(LOW, HIGH, (int(uniform.sum()), DIM))
        goals[uniform] = rng.uniform(LOW, HIGH, (int(uniform.sum()), DIM))
        starts[:, 2], goals[:, 2] = wrap_angle(starts[:, 2]), wrap_angle(goals[:, 2])
        return starts, goals


def make_queries(
    work: Workload, starts: np.ndarray, goals: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Half near cached entries (some reversed), half fresh workload draws."""
    rng = work.rng
    near = n // 2
    pick = rng.integers(0, len(starts), near)
    swap = (rng.random(near) < 0.25)[:, None]
    qs = np.where(swap, goals[pick], starts[pick]) + rng.uniform(-0.03, 0.03, (near, DIM))
    qg = np.where(swap, starts[pick], goals[pick]) + rng.uniform(-0.03, 0.03, (near, DIM))
    fs, fg = work.draw(n - near)
    return np.r_[qs, fs], np.r_[qg, fg]


def brute_force(
    ids: np.ndarray, starts: np.ndarray, goals: np.ndarray, s: np.ndarray, g: np.ndarray
) -> list[tuple[int, bool]]:
    """The top LIMIT (id, reversed) by a full numpy scan."""
    rows = []
    for rev, (first, second) in enumerate(((starts, goals), (goals, starts))):
        b1, a1 = state_distance(first, s, base=BASE)
        b2, a2 = state_distance(second, g, base=BASE)
        ok = (b1 < THRESHOLD) & (a1 < THRESHOLD) & (b2 < THRESHOLD) & (a2 < THRESHOLD)
        score = (b1 + a1 + b2 + a2)[ok]
        rows += [(float(c), int(i), rev) for c, i in zip(score, ids[ok], strict=True)]
    seen: dict[int, bool] = {}
    for _, i, rev in sorted(rows):
        seen.setdefault(i, bool(rev))
    return list(seen.items())[:LIMIT]


def time_queries(
    index: TrajectoryIndex, qs: np.ndarray, qg: np.ndarray, arm_only: bool
) -> tuple[np.ndarray, float]:
    """Per-query milliseconds and mean matches returned."""
    ms, hits = np.empty(len(qs)), 0
    for k, (s, g) in enumerate(zip(qs, qg, strict=True)):
        t0 = time.perf_counter()
        found = index.query(s, g, threshold=THRESHOLD, limit=LIMIT, arm_only=arm_only)
        ms[k] = (time.perf_counter() - t0) * 1e3
        hits += len(found)
    return ms, hits / len(qs)


def rss_bytes() -> int:
    """Resident set size of this process."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


Entries = tuple[np.ndarray, np.ndarray, np.ndarray]  # ids, starts, goals


def grow_to(index: TrajectoryIndex, data: Entries, n_main: int, size: int) -> tuple[int, float]:
    """Add entries up to `size`: a rebuilt main block, then the largest delta that does not
    rebuild; (the delta's size, the seconds to grow and rebuild the main block)."""
    ids, starts, goals = data
    delta = index.delta_limit(size - index.delta_limit(size))  # largest that won't rebuild
    delta = min(delta, size // 4)
    t0 = time.perf_counter()
    grow, recent = slice(n_main, size - delta), slice(size - delta, size)
    index.add(ids[grow], starts[grow], goals[grow])
    index.rebuild()  # main block: everything but the delta
    build_s = time.perf_counter() - t0
    index.add(ids[recent], starts[recent], goals[recent])
    assert len(index) == size and index.delta_size == delta
    return delta, build_s


def measure_size(
    index: TrajectoryIndex,
    work: Workload,
    data: Entries,
    size: int,
    n_queries: int,
    delta: int,
    build_s: float,
) -> dict[str, float]:
    """Time queries of both kinds against the first `size` entries; the table's row."""
    _, starts, goals = data
    qs, qg = make_queries(work, starts[:size], goals[:size], n_queries)
    ms, hits = time_queries(index, qs, qg, arm_only=False)
    still = qs.copy()
    still_goal = qg.copy()
    still_goal[:, :3] = still[:, :3]  # base-still requests, served from anywhere
    arm_ms, arm_hits = time_queries(index, still, still_goal, arm_only=True)
    mem = index.memory_bytes()
    return {
        "size": size,
        "delta": delta,
        "build_s": build_s,
        "p50_ms": float(np.percentile(ms, 50)),
        "p99_ms": float(np.percentile(ms, 99)),
        "hits_per_query": hits,
        "arm_only_p50_ms": float(np.percentile(arm_ms, 50)),
        "arm_only_p99_ms": float(np.percentile(arm_ms, 99)),
        "arm_only_hits_per_query": arm_hits,
        "bytes_per_entry": (mem["main"] + mem["delta"]) / size,
        "arm_only_bytes_per_entry": mem["arm_only"] / size,
    }


def print_row(row: dict[str, float]) -> None:
    """One line of the table."""
    print(
        f"{row['size']:>9} {row['delta']:>6} {row['build_s']:>8.2f} {row['p50_ms']:>7.3f}"
        f" {row['p99_ms']:>7.3f} {row['hits_per_query']:>7.2f} {row['arm_only_p50_ms']:>8.3f}"
        f" {row['arm_only_p99_ms']:>8.3f} {row['arm_only_hits_per_query']:>8.2f}"
        f" {row['bytes_per_entry']:>8.0f} {row['arm_only_bytes_per_entry']:>7.0f}"
    )


def mismatches_against_brute_force(
    index: TrajectoryIndex, work: Workload, data: Entries, size: int
) -> int:
    """How many of 200 queries the index answers differently from a brute-force scan."""
    ids, starts, goals = data
    qs, qg = make_queries(work, starts[:size], goals[:size], 200)
    return sum(
        [(m.trajectory_id, m.reversed) for m in index.query(s, g, limit=LIMIT)]
        != brute_force(ids[:size], starts[:size], goals[:size], s, g)
        for s, g in zip(qs, qg, strict=True)
    )


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="only up to 10⁴, fewer queries")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    sizes = [1_000, 10_000] if args.smoke else [1_000, 10_000, 100_000, 1_000_000]
    n_queries = 300 if args.smoke else 1000
    work = Workload(np.random.default_rng(args.seed))
    starts, goals = work.draw(sizes[-1])
    ids = np.arange(sizes[-1], dtype=np.int64) * 7 + 11  # not dense, not 0-based
    data = (ids, starts, goals)
    rss0 = rss_bytes()
    index = TrajectoryIndex(DIM, base=BASE, background_rebuild=False)
    index.query(starts[0], goals[0], arm_only=True)  # arm-only tree is kept from now on
    header = (
        f"{'size':>9} {'delta':>6} {'grow s':>8} {'p50 ms':>7} {'p99 ms':>7} {'hits/q':>7}"
        f" {'arm p50':>8} {'arm p99':>8} {'arm hits':>8} {'B/entry':>8} {'+arm B':>7}"
    )
    print(header)
    rows, mismatches, n_main = [], None, 0
    for size in sizes:
        delta, build_s = grow_to(index, data, n_main, size)
        n_main = size
        row = measure_size(index, work, data, size, n_queries, delta, build_s)
        rows.append(row)
        print_row(row)
        if size == 10_000:
            mismatches = mismatches_against_brute_force(index, work, data, size)
            print(f"brute-force check at 10⁴: 200 queries, {mismatches} mismatches")
    last = rows[-1]
    rss_per_entry = (rss_bytes() - rss0) / last["size"]
    print(
        f"memory: {last['bytes_per_entry']:.0f} B/entry main+delta (array nbytes + 72 B/tree node),"
        f" {last['arm_only_bytes_per_entry']:.0f} B/entry arm-only tree;"
        f" RSS growth {rss_per_entry:.0f} B/entry"
    )
    # in smoke mode the *_at_1e6 keys hold the largest size measured (see largest_size)
    result = {
        "smoke": args.smoke,
        "largest_size": last["size"],
        "p50_ms_at_1e6": last["p50_ms"],
        "p99_ms_at_1e6": last["p99_ms"],
        "arm_only_p50_ms_at_1e6": last["arm_only_p50_ms"],
        "bytes_per_entry": last["bytes_per_entry"],
        "arm_only_bytes_per_entry": last["arm_only_bytes_per_entry"],
        "rss_bytes_per_entry": rss_per_entry,
        "bytes_method": "sum of array nbytes + 72 B per KD-tree node",
        "mismatches": mismatches,
        "rows": rows,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
