"""The compiled planner (`compiled`): RRT-Connect whose loop runs in numba on sphere trees.

The search and its simplification run in `planning/compiled/search.py` with no Python per
iteration: sampling, nearest neighbour, extension and motion checks (at the spec's resolution,
coarse samples first) on the robot's sphere trees against the scene's primitives
(`geometry/collision/compiled/spheres.py`). Where the trees neither prove a state free nor
colliding, the motion waits in a buffer; between rounds of at most `ROUND_ITERATIONS`
iterations, Python checks those states exactly (FCL, the checker every planner uses) and the
deadline, and the next round adds the motions found free. So the trees never block a motion
that the exact check lets through, and the budget is overrun by at most one round.

The path found is then finished as every planner's is (`attempts.plan_until_certified`):
shortcut, certified validation, repair; only certified paths are SOLVED.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from trajcache.geometry.collision.checker import COLLIDING as EXACT_COLLIDING
from trajcache.geometry.collision.sphere_tables import SphereTables, sphere_tables
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.attempts import Finisher, plan_until_certified
from trajcache.planning.compiled.search import (
    FREE,
    FULL,
    OPEN,
    SOLVED,
    motion,
    rrt_connect,
    sample_count,
    seed,
    simplify,
)
from trajcache.planning.deadline import Deadline
from trajcache.planning.motion import SHORTCUT_CLEARANCE_M
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlanResult
from trajcache.planning.query import Query, prepare_query
from trajcache.planning.rris import rris_search

NAME = "compiled"
ROUND_ITERATIONS = 256  # iterations between two returns to Python (exact checks, the clock)
TREE_CAPACITY = 16_384  # nodes per tree
PENDING = 64  # motions waiting for the exact check
SIMPLIFY_ITERATIONS = 24
# The extension step (over all planning values): an arm's on MBM, where half a radian checks a
# third fewer states than one (p50 and p90, in process), and a planar base's, whose drives span
# metres (the reference workload is slower at half a metre).
RANGE, PLANAR_RANGE = 0.5, 1.0
REPAIR_S = 0.1  # one path's repair: past that, a new compiled search is the better bet
TABLE_SHARE = 0.2  # of the budget, at most, for building missing pair tables (kept after)
_COUNTERS = (
    "search_ms", "simplify_ms", "simplify_states", "rounds", "open_motions", "exact_checks",
    "tree_nodes",
)  # fmt: skip


@dataclass
class _Search:
    """One query's compiled search: the tables, buffers and counters."""

    query: Query
    tables: SphereTables
    stats: dict[str, float]
    work: tuple[np.ndarray, ...] = field(init=False)
    space: tuple[object, ...] = field(init=False)

    def __post_init__(self) -> None:
        spec = self.query.spec
        self.work = self.tables.work()
        res = spec.resolution
        step = np.full(spec.dof, res.joint_rad)
        for joint in spec.model.joints:
            if joint.index >= 0 and joint.mimic is None and joint.kind == "prismatic":
                step[joint.index] = res.position_m
        if spec.planar:
            step[:3] = (res.position_m / np.sqrt(2.0), res.position_m / np.sqrt(2.0),
                        res.orientation_rad)  # fmt: skip
        lower, upper = spec.lower.astype(float), spec.upper.astype(float)
        self.space = (lower, upper, step, bool(spec.planar), PLANAR_RANGE if spec.planar else RANGE)

    def _args(self) -> tuple[object, ...]:
        t = self.tables
        return (self.space, t.fk, t.robot, t.scene, t.pairs, self.work)

    def motion_free(self, a: FloatArray, b: FloatArray) -> bool:
        """A motion the trees prove free, or whose open states the exact check finds free."""
        status, opened = self._open_states(a, b)
        if status == OPEN:
            return self._exact(opened)
        return bool(status == FREE)

    def _open_states(self, a: FloatArray, b: FloatArray) -> tuple[int, FloatArray]:
        """The trees' verdict on the motion a → b, and its OPEN samples (coarse first)."""
        out = np.empty((sample_count(a, b, self.space), len(a)))
        status, count = motion(a, b, *self._args(), out)  # type: ignore[call-arg]
        return int(status), out[:count]

    def _exact(self, states: FloatArray) -> bool:
        self.stats["exact_checks"] += len(states)
        checker = self.query.checker.checker
        return bool(checker.check(states, stop_at_first=True).first_collision < 0)

    def run(self, deadline: Deadline) -> FloatArray | None:
        """RRT-Connect within the deadline, then simplification; the path or None."""
        q = self.query
        dof = q.spec.dof
        nodes = np.zeros((2, TREE_CAPACITY, dof))
        parent = np.full((2, TREE_CAPACITY), -1, dtype=np.int64)
        nodes[0, 0], nodes[1, 0] = q.start, q.goal
        tree = (nodes, parent, np.ones(2, dtype=np.int64))
        pending = (
            np.zeros(PENDING, dtype=np.int64),
            np.zeros(PENDING, dtype=np.int64),
            np.zeros((PENDING, dof)),
            np.zeros(PENDING, dtype=np.int64),
            np.zeros(PENDING, dtype=np.int8),
            np.zeros(1, dtype=np.int64),
        )
        out = np.zeros((2 * TREE_CAPACITY + 2, dof))
        began = time.perf_counter()
        while True:
            code, length = rrt_connect(tree, pending, *self._args(), ROUND_ITERATIONS, out)  # type: ignore[call-arg]
            self.stats["rounds"] += 1
            if code == SOLVED:
                break
            if code == FULL or deadline.expired():
                self.stats["search_ms"] += (time.perf_counter() - began) * 1e3
                return None
            self._resolve(tree, pending)
        self.stats["search_ms"] += (time.perf_counter() - began) * 1e3
        self.stats["tree_nodes"] += float(tree[2].sum())
        began = time.perf_counter()
        checked = self.work[7][0]
        count = simplify(out, length, *self._args(), SIMPLIFY_ITERATIONS)  # type: ignore[call-arg]
        self.stats["simplify_states"] += float(self.work[7][0] - checked)
        self.stats["simplify_ms"] += (time.perf_counter() - began) * 1e3
        return np.array(out[:count])

    def _resolve(self, tree: tuple[np.ndarray, ...], pending: tuple[np.ndarray, ...]) -> None:
        """Decide each pending motion by the exact check of its open states: free when none of
        them collides. Checked in two batches, since a batch costs ~40 µs and a state ~9 µs
        more (Panda, cage): first every motion's first open state (coarse first: nearly always
        the one that collides), then the other open states of the motions still undecided."""
        nodes = tree[0]
        p_tree, p_parent, p_state, _, p_ok, p_count = pending
        count = int(p_count[0])
        self.stats["open_motions"] += float(count)
        opened: list[FloatArray] = []
        for k in range(count):
            status, found = self._open_states(nodes[p_tree[k], p_parent[k]], p_state[k])
            opened.append(found if status == OPEN else found[:0])
            p_ok[k] = 1 if status == FREE else 0
        firsts = [k for k in range(count) if len(opened[k])]
        if not firsts:
            return
        first_free = self._free_states(np.stack([opened[k][0] for k in firsts]))
        rest = [k for k, free in zip(firsts, first_free, strict=True) if free]
        if not rest:
            return
        states = [opened[k][1:] for k in rest]
        verdicts = self._free_states(np.concatenate(states)) if sum(map(len, states)) else []
        at = 0
        for k, some in zip(rest, states, strict=True):
            p_ok[k] = 1 if all(verdicts[at : at + len(some)]) else 0
            at += len(some)

    def _free_states(self, states: FloatArray) -> list[bool]:
        """Whether each state is free by the exact check (one batch)."""
        self.stats["exact_checks"] += len(states)
        verdict = self.query.checker.checker.check(states, stop_at_first=False)
        return [bool(s != EXACT_COLLIDING) for s in verdict.status]


def plan_compiled(
    problem_model: RobotModel,
    scene: Scene,
    start: Sequence[float] | FloatArray,
    goal: Sequence[float] | FloatArray,
    options: SearchOptions,
) -> PlanResult:
    """Plan start → goal with the compiled planner; SOLVED paths passed the validator that
    `options` set up."""
    budget_s, resolution, certified = options.budget_s, options.resolution, options.certified
    deadline = Deadline(budget_s)
    began = time.perf_counter()
    prepared = prepare_query(problem_model, scene, start, goal, resolution=resolution)
    if isinstance(prepared, PlanResult):
        return prepared
    query = prepared
    rng = np.random.default_rng(options.seed)
    seed(int(options.seed) % (2**32))
    validator = TrajectoryValidator(
        problem_model, scene, resolution=resolution, certified=certified
    )
    stats: dict[str, float] = {"straight": 0.0, **dict.fromkeys(_COUNTERS, 0.0)}
    tables_began = time.perf_counter()
    tables = sphere_tables(query.checker.checker, TABLE_SHARE * budget_s)
    search = _Search(query, tables, stats)
    stats["tables_ms"] = (time.perf_counter() - tables_began) * 1e3
    stats["endpoints_ms"] = (tables_began - began) * 1e3
    stats["plan_ms"] = stats["endpoints_ms"] + stats["tables_ms"]

    def search_fn(attempt: int, deadline: Deadline) -> FloatArray | None:
        if attempt == 0 and search.motion_free(query.start, query.goal):
            stats["straight"] = 1.0
            return np.stack([query.start, query.goal])
        if deadline.expired():
            return None
        return search.run(deadline)

    finisher = Finisher(
        query=query,
        validator=validator,
        segment_fn=lambda a, b: query.checker.segment_free(a, b, SHORTCUT_CLEARANCE_M),
        detour_fn=lambda q, d, certify: rris_search(q, d, rng, segment_free_fn=certify),
        deadline=deadline,
        rng=rng,
        shortcut_s=options.shortcut_s,
        stats=stats,
        repair_s=REPAIR_S,
    )
    result = plan_until_certified(
        finisher, search_fn=search_fn, none_found="no path found within the time budget"
    )
    stats.update(query.checker.stats())
    counts = search.work[7]
    stats["sphere_states"], stats["sphere_open"] = float(counts[0]), float(counts[1])
    stats["total_ms"] = (time.perf_counter() - began) * 1e3
    return result


def warm_compiled(model: RobotModel, scene: Scene, start: FloatArray, goal: FloatArray) -> None:
    """Compile (or load from numba's cache) the search kernels with the types a plan passes:
    a motion check, rounds of the search and a simplification, for valid `start` and `goal`."""
    query = prepare_query(model, scene, start, goal)
    if isinstance(query, PlanResult):
        raise ValueError(f"warm-up query refused: {query.message}")
    search = _Search(query, sphere_tables(query.checker.checker), dict.fromkeys(_COUNTERS, 0.0))
    search.motion_free(query.start, query.goal)
    search.run(Deadline(0.01))
    path = np.ascontiguousarray(np.stack([query.start, query.goal, query.start]))
    simplify(path, 3, *search._args(), 1)  # type: ignore[call-arg]
