"""Inverse kinematics: a state that puts a link at a pose, within tolerances, limits and a
validity predicate, nearest a seed among several solutions.

Solver: damped least squares on Pinocchio's kinematics (`pin_kinematics`), with joint limits
held by projection. Each attempt iterates from a start state

    e = log6(T(s)⁻¹ · T*)   (the pose error in the link's frame, 6-vector)
    J = J_link(q(s)) · V(s) restricted to the moving columns (the arm; the base too if allowed)
    Δs = Jᵀ (J Jᵀ + λ² I)⁻¹ e,   scaled down so that no value moves more than MAX_STEP
    s ← s + Δs, clipped into the joint limits (wrapped, for joints that turn a full turn)

until the position error is within `position_tolerance` and the rotation angle between the
link's orientation and the target's within `orientation_tolerance`, each scaled by MARGIN so
that a solution is inside the tolerances by more than rounding; or until MAX_ITERATIONS, or
STALL_ITERATIONS without progress. Attempts start from the seed, then from the given starts
(cached states), then from random states (seeded rng) within a window about the seed that
widens by RESTART_SPREAD of each joint's range per restart, until
`solutions` distinct states reach the pose or the time budget is spent. The answer is the valid
one nearest the seed (Euclidean over the moving values, angles of full-turn joints wrapped
toward the seed): they are checked by `valid_fn` (a collision check, the costly part) nearest
first, and the first valid one is the answer; when none is, the search goes on for as many
more. A state that fails `valid_fn` is counted, not returned: no valid solution with some
invalid ones is IN_COLLISION, none at all NOT_FOUND.

Why this solver (`bench/ik.py`: 200 random reachable poses each of the MotionBenchMaker Panda's
hand and the reference robot's tool tip, 1 mm and 0.01 rad, from the ready or stowed state, a
50 ms budget; every answer checked with yourdfpy; this shared 2-core machine):

    solver (median / p95 ms)      Panda        reference    solved
    damped least squares, 1st     0.47 / 3.9   0.53 / 1.8   100 %, 100 %
    the same, nearest of 3        1.9 / 10.5   1.2 / 5.0    100 %, 100 %
    pin-pink (QP per step, daqp)  1.19 / 37.0  1.28 / 11.3  97.5 %, 99 %

Damped least squares is faster at the median, has the much shorter tail (pin-pink builds and
solves a QP at every step) and solves every pose, with nothing beyond Pinocchio: it is the
service's solver. Earlier runs ranked them the same (first solution 0.45-0.53 ms on the Panda,
pin-pink 0.74-1.08 ms). Through the live service (`--service`, the route's defaults: 3
solutions, collision-checked) the server answers in 2.65 ms (Panda) and 2.27 ms (reference) at
the median; the poses it leaves unsolved are reached only in self-collision.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
import weakref
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import cast

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.shapes import FloatArray

MAX_ITERATIONS = 50
STALL_ITERATIONS = 8  # iterations without a 1% drop of the error end an attempt
DAMPING = 1e-2  # λ
MAX_STEP = 1.0  # rad or m per iteration, per value
RESTART_SPREAD = 0.15  # the k-th random restart draws within k × 15% of each range of the seed
MARGIN = 0.5  # a solution's errors are within MARGIN × the tolerances
_FULL_TURN = 2 * math.pi - 1e-9


@dataclass(frozen=True)
class PoseTarget:
    """Where a link must be: a 4×4 pose in the world frame (a fixed base's root frame), and how
    close (metres; radians of the rotation between the two orientations)."""

    link: str
    pose: FloatArray
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2


@dataclass(frozen=True)
class IkProblem:
    """One IK query: the target, the seed state, what may move and the budget."""

    kinematics: PinKinematics
    target: PoseTarget
    seed: FloatArray  # a state in `state_names` order; the answer is nearest it
    move_base: bool = False  # a planar base's x, y, θ move too
    starts: Sequence[FloatArray] = ()  # further start states tried before random ones
    valid_fn: Callable[[FloatArray], bool] | None = None  # None: every state is valid
    solutions: int = 3  # distinct states reaching the pose to compare before answering
    budget_s: float = 0.05
    rng_seed: int = 0
    hold_limits: bool = False  # values at a limit that a step would push out are held
    window: float | None = None  # rad: random restarts stay this close to the seed's values
    clock: Callable[[], float] = field(default=time.perf_counter, repr=False)


class IkStatus(str, Enum):
    """How an IK query ended."""

    SUCCESS = "success"
    NOT_FOUND = "not_found"  # no state reached the pose within the budget
    IN_COLLISION = "in_collision"  # states reached it, but none was valid


@dataclass(frozen=True)
class IkResult:
    """The answer: the state (None unless SUCCESS) and what the search did."""

    status: IkStatus
    state: FloatArray | None
    solutions: int  # distinct states found that reach the pose (valid or not)
    rejected: int  # of them, those checked and failing valid_fn
    attempts: int
    iterations: int
    position_error: float | None = None  # of the answer (m)
    orientation_error: float | None = None  # of the answer (rad)


@dataclass
class _Setup:
    """What every attempt of a problem shares."""

    frame: int
    columns: np.ndarray  # state values that move
    lower: FloatArray  # their limits (−inf/inf for a base's x, y)
    upper: FloatArray
    turns: np.ndarray  # which of them wrap over a full turn
    any_turns: bool
    velocity: FloatArray | None  # V(s) of the moving columns, when the base does not turn
    target: pin.SE3
    tolerances: tuple[float, float]
    data: pin.Data  # Pinocchio's workspace, one per kinematics and thread
    hold_limits: bool = False
    reached: tuple[float, float] = (math.inf, math.inf)  # the last descent's errors at its end


def solve_ik(problem: IkProblem) -> IkResult:
    """The valid state nearest the seed that puts the link at the target, or why there is none."""
    ends = problem.clock() + max(0.0, problem.budget_s)
    setup = _setup(problem)
    seen: list[FloatArray] = []  # every distinct state that reached the pose
    pending: list[FloatArray] = []  # those not yet checked by valid_fn
    errors: dict[int, tuple[float, float]] = {}  # by id of a state seen: its pose errors
    best: FloatArray | None = None
    rejected = attempts = iterations = 0
    for start in _starts(problem):
        if attempts and problem.clock() >= ends:
            break
        attempts += 1
        state, used = _descend(problem.kinematics, setup, start, ends, problem.clock)
        iterations += used
        if state is None or any(_same(state, other, setup) for other in seen):
            continue
        seen.append(state)
        errors[id(state)] = setup.reached
        pending.append(state)
        if len(pending) >= problem.solutions:
            best, failed = _nearest_valid(problem, setup, pending)
            rejected, pending = rejected + failed, []
            if best is not None:
                break
    if best is None and pending:  # the budget ran out with solutions still to check
        best, failed = _nearest_valid(problem, setup, pending)
        rejected += failed
    if best is None:
        status = IkStatus.IN_COLLISION if rejected else IkStatus.NOT_FOUND
        return IkResult(status, None, len(seen), rejected, attempts, iterations)
    position, orientation = errors[id(best)]  # as the descent measured them where it ended
    return IkResult(
        IkStatus.SUCCESS, best, len(seen), rejected, attempts, iterations, position, orientation
    )


def descend_from_seed(problem: IkProblem) -> FloatArray | None:
    """Damped least squares from the seed alone (a warm start: no restarts, no `valid_fn`):
    the state that reaches the target, or None."""
    setup = _setup(problem)
    ends = problem.clock() + max(0.0, problem.budget_s)
    state, _ = _descend(problem.kinematics, setup, problem.seed, ends, problem.clock)
    return state


def _nearest_valid(
    problem: IkProblem, setup: _Setup, states: list[FloatArray]
) -> tuple[FloatArray | None, int]:
    """The valid state of `states` nearest the seed, and how many nearer ones were invalid:
    checked nearest first, so valid_fn (a collision check) runs as few times as it can."""
    invalid = 0
    for state in sorted(states, key=lambda s: _distance(s, problem.seed, setup)):
        if problem.valid_fn is None or problem.valid_fn(state):
            return state, invalid
        invalid += 1
    return None, invalid


def _setup(problem: IkProblem) -> _Setup:
    target, kin = problem.target, problem.kinematics
    columns, lower, upper, turns = _columns(kin, problem.move_base)
    return _Setup(
        frame=kin.frame_id(target.link),
        columns=columns,
        lower=lower,
        upper=upper,
        turns=turns,
        any_turns=bool(turns.any()),
        velocity=None if problem.move_base else kin.velocity_of(problem.seed)[:, columns],
        target=pin.SE3(np.asarray(target.pose, dtype=float)),
        tolerances=(target.position_tolerance, target.orientation_tolerance),
        data=_data(kin),
        hold_limits=problem.hold_limits,
    )


_Columns = tuple[np.ndarray, FloatArray, FloatArray, np.ndarray]
_COLUMNS: weakref.WeakKeyDictionary[PinKinematics, dict[bool, _Columns]] = (
    weakref.WeakKeyDictionary()
)
_DATA = threading.local()  # per thread: Pinocchio workspaces by kinematics


def _columns(kin: PinKinematics, move_base: bool) -> _Columns:
    """The state values IK moves, their limits and which wrap over a full turn: constants of
    the kinematics, computed once (never written to)."""
    known = _COLUMNS.setdefault(kin, {})
    if move_base not in known:
        model = kin.model
        columns = np.arange(0 if move_base else model.arm_offset, model.dof)
        lower, upper = model.lower[columns].astype(float), model.upper[columns].astype(float)
        if model.arm_offset and move_base:
            lower[:2], upper[:2] = -np.inf, np.inf
            lower[2], upper[2] = -math.pi, math.pi
        turns = np.isfinite(upper - lower) & (upper - lower >= _FULL_TURN)
        for array in (columns, lower, upper, turns):
            array.flags.writeable = False
        known[move_base] = (columns, lower, upper, turns)
    return known[move_base]


def _data(kin: PinKinematics) -> pin.Data:
    """This thread's Pinocchio workspace for `kin` (a solve runs on one thread, start to end)."""
    workspaces = getattr(_DATA, "by_kinematics", None)
    if workspaces is None:
        workspaces = _DATA.by_kinematics = weakref.WeakKeyDictionary()
    data = workspaces.get(kin)
    if data is None:
        data = workspaces[kin] = kin.pin_model.createData()
    return data


def _starts(problem: IkProblem, rng: np.random.Generator | None = None) -> Iterator[FloatArray]:
    """The seed, the given starts, then random states around the seed: the arm within the
    limits, each value within a window about the seed that widens to the whole range, or to
    `window` at most (restarts near the seed converge more often, and to solutions nearer it);
    the seed's base."""
    seed = np.asarray(problem.seed, dtype=float)
    yield seed.copy()
    for start in problem.starts:
        yield np.asarray(start, dtype=float).copy()
    model = problem.kinematics.model
    arm = np.arange(model.arm_offset, model.dof)
    lower, upper = model.lower[arm], model.upper[arm]
    if rng is None:  # made only when restarts are needed: most solves end at the seed
        rng = np.random.default_rng(problem.rng_seed)
    for restart in itertools.count(1):
        spread = min(1.0, RESTART_SPREAD * restart) * (upper - lower)
        if problem.window is not None:
            spread = np.minimum(spread, problem.window)
        state = seed.copy()
        low, high = np.maximum(lower, seed[arm] - spread), np.minimum(upper, seed[arm] + spread)
        state[arm] = rng.uniform(low, high)
        yield state


def _descend(
    kin: PinKinematics,
    setup: _Setup,
    start: FloatArray,
    ends: float,
    clock: Callable[[], float],
) -> tuple[FloatArray | None, int]:
    """Damped least squares from `start`: the converged state (None if it is not reached) and
    the iterations it took."""
    model, data = kin.pin_model, setup.data
    state = start.copy()
    state[setup.columns] = _bounded(state[setup.columns], setup)
    best, stalled = math.inf, 0
    position_goal, orientation_goal = (MARGIN * t for t in setup.tolerances)
    damping = np.eye(6) * DAMPING**2
    for iteration in range(1, MAX_ITERATIONS + 1):
        q = kin.q_of(state)
        pin.computeJointJacobians(model, data, q)
        current = pin.updateFramePlacement(model, data, setup.frame)
        error = pin.log6(current.actInv(setup.target)).vector
        gap = setup.target.translation - current.translation
        position = math.sqrt(gap @ gap)
        orientation = math.sqrt(error[3:] @ error[3:])  # log6's rotation part is log3's
        if position <= position_goal and orientation <= orientation_goal:
            setup.reached = (position, orientation)
            return state, iteration
        size = position + orientation
        stalled = 0 if size < 0.99 * best else stalled + 1
        best = min(best, size)
        if stalled >= STALL_ITERATIONS or (iteration % 16 == 0 and clock() >= ends):
            return None, iteration
        jacobian = pin.getFrameJacobian(model, data, setup.frame, pin.LOCAL)
        velocity = setup.velocity
        if velocity is None:
            velocity = kin.velocity_of(state)[:, setup.columns]
        step = _step(jacobian @ velocity, error, damping, state[setup.columns], setup)
        largest = float(np.abs(step).max())
        if largest > MAX_STEP:
            step *= MAX_STEP / largest
        state[setup.columns] = _bounded(state[setup.columns] + step, setup)
    return None, MAX_ITERATIONS


def _step(
    jac: FloatArray, error: FloatArray, damping: FloatArray, values: FloatArray, setup: _Setup
) -> FloatArray:
    """The damped least-squares step; with `hold_limits`, the values at a limit that it would
    push out are held and the step solved again without them (the others take up the motion,
    where projection alone would stall)."""
    step = jac.T @ _solve_spd(jac @ jac.T + damping, error)
    if not setup.hold_limits:
        return step
    held = ((values <= setup.lower) & (step < 0)) | ((values >= setup.upper) & (step > 0))
    held &= ~setup.turns
    if not held.any():
        return step
    free = jac.copy()
    free[:, held] = 0.0
    return free.T @ _solve_spd(free @ free.T + damping, error)


def _solve_spd(a: FloatArray, b: FloatArray) -> FloatArray:
    """x with a·x = b for a symmetric positive definite `a` (LAPACK's Cholesky solver, a third
    of numpy's general solve's cost on a 6×6)."""
    _, x, info = dposv(a, b)
    return cast(FloatArray, x if info == 0 else np.linalg.solve(a, b))


def _bounded(values: FloatArray, setup: _Setup) -> FloatArray:
    """Values clipped into the limits; full-turn joints wrapped into their window instead."""
    bounded = np.minimum(np.maximum(values, setup.lower), setup.upper)  # np.clip's cost/3
    if setup.any_turns:
        turns, lower = setup.turns, setup.lower[setup.turns]
        bounded[turns] = lower + np.mod(values[turns] - lower, 2 * math.pi)
    return bounded


def _delta(a: FloatArray, b: FloatArray, setup: _Setup) -> FloatArray:
    """a − b over the moving values, full-turn joints by the shorter way round."""
    gap = a[setup.columns] - b[setup.columns]
    return np.where(setup.turns, np.remainder(gap + math.pi, 2 * math.pi) - math.pi, gap)


def _distance(a: FloatArray, b: FloatArray, setup: _Setup) -> float:
    return float(np.linalg.norm(_delta(a, b, setup)))


def _same(a: FloatArray, b: FloatArray, setup: _Setup) -> bool:
    """Whether two solutions are the same one (every value within 1 mrad or 1 mm)."""
    return bool(np.abs(_delta(a, b, setup)).max() <= 1e-3)


def pose_errors(
    kin: PinKinematics, frame: int, state: FloatArray, target: pin.SE3
) -> tuple[float, float]:
    """Position (m) and rotation angle (rad) between the frame at `state` and `target`."""
    pose = pin.SE3(kin.link_pose(state, frame))
    position = float(np.linalg.norm(target.translation - pose.translation))
    return position, float(np.linalg.norm(pin.log3(pose.rotation.T @ target.rotation)))
