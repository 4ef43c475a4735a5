"""OMPL (Python bindings) as the fallback planner.

State space: SE2 for a moving planar base plus RealVector(n) for the joints; RealVector(n) alone
when the base is fixed or does not move in the query (the base is then held at its pose, as the
paper's adaptation step assumes). BIT*'s informed sampler does not support compound spaces, so
for BIT* the base angle becomes a bounded real (segments still take the short way, see below).

Motion validation: a `MotionValidator` subclass (the nanobind bindings allow it) whose
`checkMotion(a, b)` calls `MotionChecker.segment_free`: the segment is sampled at the
validator's resolution (the service's settings, by default the paper's: 0.04 m, 0.04 rad, 0.035
rad per joint; θ the short way) and every sample goes into ONE batched collision check, coarse
samples first, stopping at the first collision. OMPL's own validator (used by `naive=True`,
the benchmark baseline) samples at a fraction of the space's maximum extent; there the fraction
is set so that OMPL's longest valid segment is no longer than the smallest step, and each state
costs one Python callback and one check call.

The result is shortcut (`shortcut.shortcut_and_certify`, new segments keep 1 cm clearance at
their samples) and must pass certified validation; a path that fails it is repaired, or another
is searched for, while the budget lasts (`attempts.plan_until_certified`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Sequence

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from trajcache.geometry.collision.checker import FREE
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import TrajectoryValidator
from trajcache.planning.attempts import Finisher, plan_until_certified
from trajcache.planning.deadline import Deadline
from trajcache.planning.motion import SHORTCUT_CLEARANCE_M
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.query import Query, prepare_query
from trajcache.planning.rris import rris_search
from trajcache.planning.space import StateSpaceSpec

PlannerFactory = Callable[[ob.SpaceInformation], ob.Planner]
PLANNERS: dict[str, PlannerFactory] = {
    "rrtconnect": og.RRTConnect,
    "rrt": og.RRT,
    "bitstar": og.BITstar,
    "bit*": og.BITstar,
    "prm": og.PRM,
    "kpiece": og.KPIECE1,
}
RANGE_FRACTION = 0.2  # RRT-family step as a fraction of the space's maximum extent

ou.setLogLevel(ou.LOG_WARN)


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Silence OMPL's log (re-seeding after the first sample logs an error, harmlessly)."""
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        yield
    finally:
        ou.setLogLevel(level)


def seed_ompl(seed: int) -> None:
    """Seed OMPL's global generator (0 is not a valid OMPL seed, hence the offset)."""
    with _quiet():
        ou.RNG.setSeed(int(seed) % (2**31 - 2) + 1)


class _Codec:
    """Converts between OMPL states and numpy states of the full model."""

    def __init__(self, spec: StateSpaceSpec, compound: bool) -> None:
        self.template = (spec.lower + spec.upper) / 2.0
        self.free = np.flatnonzero(~spec.held)  # state values OMPL plans over
        self.compound = compound
        self.count = len(self.free)

    def array(self, state: ob.State) -> FloatArray:
        out = self.template.copy()
        if self.compound:
            base, arm = state[0], state[1]
            out[0], out[1], out[2] = base.getX(), base.getY(), base.getYaw()
            out[3:] = [arm[i] for i in range(self.count - 3)]
        else:
            out[self.free] = [state[i] for i in range(self.count)]
        return out

    def fill(self, space: ob.StateSpace, values: FloatArray) -> ob.State:
        state = space.allocState()
        space.copyFromReals(state, [float(v) for v in np.asarray(values)[self.free]])
        return state


def _bounds(lower: FloatArray, upper: FloatArray) -> ob.RealVectorBounds:
    bounds = ob.RealVectorBounds(len(lower))
    for i, (lo, hi) in enumerate(zip(lower, upper, strict=True)):
        bounds.setLow(i, float(lo))
        bounds.setHigh(i, float(hi))
    return bounds


def _state_space(spec: StateSpaceSpec, compound: bool) -> ob.StateSpace:
    free = np.flatnonzero(~spec.held)
    if not compound:
        space = ob.RealVectorStateSpace(len(free))
        space.setBounds(_bounds(spec.lower[free], spec.upper[free]))
        return space
    base = ob.SE2StateSpace()
    base.setBounds(_bounds(spec.lower[:2], spec.upper[:2]))
    arm = ob.RealVectorStateSpace(spec.dof - 3)
    arm.setBounds(_bounds(spec.lower[3:], spec.upper[3:]))
    space = ob.CompoundStateSpace()
    space.addSubspace(base, 1.0)
    space.addSubspace(arm, 1.0)
    return space


class SegmentMotionValidator(ob.MotionValidator):
    """OMPL motion validation by one call for the whole segment: certified (the compiled
    bounds over the paper-resolution samples and every motion between them), or one batched
    check of those samples."""

    def __init__(
        self,
        si: ob.SpaceInformation,
        codec: _Codec,
        segment_fn: Callable[[FloatArray, FloatArray], bool],
    ) -> None:
        super().__init__(si)
        self._codec = codec
        self._segment_fn = segment_fn

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:
        """True when the straight motion s1 → s2 is free (s1 assumed valid)."""
        return self._segment_fn(self._codec.array(s1), self._codec.array(s2))


def _naive_resolution(spec: StateSpaceSpec, space: ob.StateSpace, compound: bool) -> float:
    """OMPL's segment fraction that keeps every per-value step within the paper's steps."""
    res = spec.resolution
    step = res.joint_rad
    if spec.planar and not spec.held[0]:
        # SE2 distance = |Δxy| + 0.5 |Δθ| (OMPL's subspace weights); a real θ counts fully
        step = min(step, res.position_m, res.orientation_rad * (0.5 if compound else 1.0))
    return step / space.getMaximumExtent()


def _setup(
    query: Query, planner: str, naive: bool, certified: bool
) -> tuple[og.SimpleSetup, _Codec, list[object]]:
    """SimpleSetup with the space, validity checking and the planner; returns keep-alives."""
    spec, checker = query.spec, query.checker
    compound = spec.planar and not spec.held[0] and planner not in ("bitstar", "bit*")
    space = _state_space(spec, compound)
    codec = _Codec(spec, compound)
    si = ob.SpaceInformation(space)
    keep: list[object] = [space, si]
    si.setStateValidityChecker(lambda s: checker.state_free(codec.array(s)))
    if naive:  # OMPL's DiscreteMotionValidator: one validity callback per sampled state
        si.setStateValidityCheckingResolution(_naive_resolution(spec, space, compound))
    else:
        validator = SegmentMotionValidator(si, codec, _segment_fn(query, naive, certified))
        si.setMotionValidator(validator)
        keep.append(validator)
    si.setup()
    if planner == "kpiece" and compound:
        space.registerDefaultProjection(ob.SubspaceProjectionEvaluator(space, 0))
    algorithm = PLANNERS[planner](si)
    if planner in ("rrtconnect", "rrt", "kpiece"):
        algorithm.setRange(RANGE_FRACTION * space.getMaximumExtent())
    if planner in ("bitstar", "bit*"):
        algorithm.setStopOnSolnImprovement(True)
    ss = og.SimpleSetup(si)
    ss.setPlanner(algorithm)
    ss.setStartAndGoalStates(codec.fill(space, query.start), codec.fill(space, query.goal))
    keep.append(algorithm)
    return ss, codec, keep


def _solve(
    query: Query, planner: str, naive: bool, certified: bool, deadline: Deadline
) -> FloatArray | None:
    """One OMPL run within the deadline; the raw path (N, D) or None."""
    ss, codec, _keep = _setup(query, planner, naive, certified)
    ptc = ob.timedPlannerTerminationCondition(deadline.remaining())
    with _quiet():
        status = ss.solve(ptc)
    if status.getStatus() != ob.PlannerStatus.EXACT_SOLUTION or not ss.haveExactSolutionPath():
        return None
    path = ss.getSolutionPath()
    return np.array([codec.array(path.getState(i)) for i in range(path.getStateCount())])


def _segment_fn(
    query: Query, naive: bool, certified: bool, clearance: float = 0.0
) -> Callable[[FloatArray, FloatArray], bool]:
    """Certified segment checks (the path then passes certified validation as it is found),
    batched sample checks, or one check call per sample for the naive baseline."""
    checker, spec = query.checker, query.spec
    if certified and not naive:
        return checker.segment_certified
    if not naive:
        return lambda a, b: checker.segment_free(a, b, clearance)

    def per_state(a: FloatArray, b: FloatArray) -> bool:
        return all(
            checker.clearance_status(s[None, :], clearance)[0] == FREE if clearance > 0.0
            else checker.state_free(s)
            for s in spec.extend(a, b)
        )  # fmt: skip

    return per_state


def plan_ompl(
    problem_model: RobotModel,
    scene: Scene,
    start: Sequence[float] | FloatArray,
    goal: Sequence[float] | FloatArray,
    options: SearchOptions,
    *,
    planner: str = "rrtconnect",
    naive: bool = False,
) -> PlanResult:
    """Plan start → goal with an OMPL planner; SOLVED paths passed the validator that
    `options` set up (`naive`: check motions by sampling alone, without the certifier)."""
    resolution, certified = options.resolution, options.certified
    deadline = Deadline(options.budget_s)
    name = planner.strip().lower()
    if name not in PLANNERS:
        valid = ", ".join(sorted(PLANNERS))
        return PlanResult(PlannerStatus.ERROR, message=f"unknown planner {planner!r}; use {valid}")
    began = time.perf_counter()
    prepared = prepare_query(problem_model, scene, start, goal, resolution=resolution)
    if isinstance(prepared, PlanResult):
        return prepared
    query = prepared
    seed_ompl(options.seed)
    rng = np.random.default_rng(options.seed)
    validator = TrajectoryValidator(
        problem_model, scene, resolution=resolution, certified=certified
    )
    endpoints_ms = (time.perf_counter() - began) * 1e3
    stats = {"plan_ms": endpoints_ms, "endpoints_ms": endpoints_ms, "straight": 0.0}

    def search(attempt: int, deadline: Deadline) -> FloatArray | None:
        if attempt == 0 and _segment_fn(query, naive, certified)(query.start, query.goal):
            stats["straight"] = 1.0
            return np.stack([query.start, query.goal])
        if deadline.expired():
            return None
        return _solve(query, name, naive, certified, deadline)

    finisher = Finisher(
        query=query,
        validator=validator,
        segment_fn=_segment_fn(query, naive, certified, SHORTCUT_CLEARANCE_M),
        detour_fn=lambda q, d, certify: rris_search(q, d, rng, segment_free_fn=certify),
        deadline=deadline,
        rng=rng,
        shortcut_s=options.shortcut_s,
        stats=stats,
    )
    result = plan_until_certified(
        finisher, search_fn=search, none_found="no path found within the time budget"
    )
    stats.update(query.checker.stats())
    stats["total_ms"] = (time.perf_counter() - began) * 1e3
    return result


def planner_names() -> list[str]:
    """The planner names `plan_ompl` accepts."""
    return sorted(PLANNERS)


__all__ = ["PLANNERS", "SegmentMotionValidator", "plan_ompl", "planner_names", "seed_ompl"]
