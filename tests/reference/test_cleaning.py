"""The cleaning-run generator: determinism, size, valid states, noise and scene changes."""

from __future__ import annotations

import collections
import itertools
import math

import numpy as np
import pytest

from trajcache.geometry.collision.checker import FREE, CollisionChecker
from trajcache.geometry.model.kinematics import check_limits
from trajcache.geometry.model.robot import RobotModel
from trajcache.reference import (
    PERTURBED_NOISE,
    TASKS,
    CleaningRun,
    Noise,
    cleaning_run,
    door_sweep_run,
    work_stations,
)
from trajcache.reference.restroom import STALL_COUNT, restroom_scene
from trajcache.reference.robot import reference_model
from trajcache.reference.tasks import OPEN_DOOR, ROUTES, SEAT_DOWN, SEAT_UP, STOW

TOL = 1e-12


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return reference_model()


@pytest.fixture(scope="module")
def run() -> CleaningRun:
    return cleaning_run(11)


@pytest.fixture(scope="module")
def perturbed() -> CleaningRun:
    return cleaning_run(11, perturbed=True)


def _arrays(run: CleaningRun) -> tuple[np.ndarray, np.ndarray]:
    return np.array([c.start for c in run.calls]), np.array([c.goal for c in run.calls])


def _colliding(model: RobotModel, run: CleaningRun) -> list[str]:
    """Every start or goal of `run` that is out of limits or not free in its scene."""
    by_scene = collections.defaultdict(list)
    for call in run.calls:
        by_scene[(call.doors_deg, call.seats_deg)].append(call)
    bad = []
    for key, calls in by_scene.items():
        states = np.array([s for c in calls for s in (c.start, c.goal)])
        check_limits(model, states)
        assert all(run.scene_for(c) is run.scene(*key) for c in calls)
        verdict = CollisionChecker(model, run.scene(*key)).check(states, stop_at_first=False)
        bad += [
            f"{calls[i // 2].index} {calls[i // 2].label} ({('start', 'goal')[i % 2]})"
            for i in np.flatnonzero(verdict.status != FREE)
        ]
    return bad


def test_same_seed_gives_identical_runs() -> None:
    a, b = cleaning_run(5), cleaning_run(5)
    for x, y in zip(_arrays(a), _arrays(b), strict=True):
        np.testing.assert_array_equal(x, y)
    assert [c.label for c in a.calls] == [c.label for c in b.calls]
    assert [(c.doors_deg, c.seats_deg) for c in a.calls] == [
        (c.doors_deg, c.seats_deg) for c in b.calls
    ]
    assert a.events == b.events


def test_other_seeds_change_noise_and_doors_but_not_the_plan() -> None:
    a, b = cleaning_run(5), cleaning_run(6)
    assert [c.label for c in a.calls] == [c.label for c in b.calls]
    assert [c.base_moves for c in a.calls] == [c.base_moves for c in b.calls]
    starts_a, starts_b = _arrays(a)[0], _arrays(b)[0]
    assert np.all(np.any(starts_a != starts_b, axis=1))  # every actual state differs
    # Similar runs: starts stay within the noise of each other (this is what caching exploits).
    assert np.max(np.abs(starts_a[:, 3:] - starts_b[:, 3:])) <= 2 * Noise().joint_rad + TOL
    assert a.events[0].doors_deg != b.events[0].doors_deg


@pytest.mark.parametrize(
    "make",
    [
        lambda: cleaning_run(0),
        lambda: cleaning_run(1, perturbed=True),
        lambda: door_sweep_run(40.0, 2),
    ],
)
def test_run_has_about_as_many_calls_as_the_paper(make: object) -> None:
    run = make()  # type: ignore[operator]
    assert 250 <= len(run.calls) <= 300
    assert [c.index for c in run.calls] == list(range(len(run.calls)))
    assert sum(c.base_moves for c in run.calls) >= STALL_COUNT + 2
    assert {c.station for c in run.calls} >= {s.name for s in work_stations()}


def test_every_state_of_a_normal_run_is_valid(model: RobotModel, run: CleaningRun) -> None:
    assert _colliding(model, run) == []


def test_every_state_of_a_perturbed_run_is_valid(model: RobotModel, perturbed: CleaningRun) -> None:
    assert _colliding(model, perturbed) == []


@pytest.mark.parametrize("door", range(0, 91, 10))
def test_every_state_of_a_door_sweep_run_is_valid(model: RobotModel, door: int) -> None:
    sweep = door_sweep_run(door, seed=door)
    assert {c.doors_deg for c in sweep.calls} == {(float(door),) * STALL_COUNT}
    assert len({c.seats_deg for c in sweep.calls}) > 1  # seats still go up and down
    assert _colliding(model, sweep) == []


@pytest.mark.parametrize("which", ["run", "perturbed"])
def test_arm_moves_keep_the_base_and_base_moves_stow_the_arm(
    which: str, request: pytest.FixtureRequest
) -> None:
    run: CleaningRun = request.getfixturevalue(which)
    noise = run.noise
    for call in run.calls:
        if call.base_moves:
            np.testing.assert_array_equal(call.goal[3:], STOW)
            assert np.max(np.abs(call.start[3:] - STOW)) <= noise.joint_rad + TOL
        else:
            np.testing.assert_array_equal(call.start[:3], call.goal[:3])
    arm_moves = [c for c in run.calls if not c.base_moves]
    assert len(arm_moves) > 200


@pytest.mark.parametrize("which", ["run", "perturbed"])
def test_each_call_starts_where_the_previous_one_actually_ended(
    which: str, request: pytest.FixtureRequest
) -> None:
    run: CleaningRun = request.getfixturevalue(which)
    noise = run.noise
    arm_errors = []
    for prev, call in itertools.pairwise(run.calls):
        arm_error = call.start[3:] - prev.goal[3:]
        assert np.max(np.abs(arm_error)) <= noise.joint_rad + TOL
        arm_errors.append(arm_error)
        if prev.base_moves:
            xy = np.abs(call.start[:2] - prev.goal[:2])
            dtheta = abs(math.remainder(call.start[2] - prev.goal[2], 2 * math.pi))
            assert np.max(xy) <= noise.base_xy_m + TOL
            assert dtheta <= noise.base_theta_rad + TOL
        else:
            np.testing.assert_array_equal(call.start[:3], prev.start[:3])
    # Noise is really there: Gaussian with σ = bound / 2 clipped to the bound (std ≈ 0.48 bound).
    assert 0.4 < np.std(np.concatenate(arm_errors)) / noise.joint_rad < 0.56


def test_perturbed_runs_are_noisier_and_jittered(run: CleaningRun, perturbed: CleaningRun) -> None:
    assert perturbed.noise == PERTURBED_NOISE
    assert PERTURBED_NOISE.joint_rad > run.noise.joint_rad
    steps = [
        np.max(np.abs(c.start[3:] - p.goal[3:])) for p, c in itertools.pairwise(perturbed.calls)
    ]
    assert max(steps) > run.noise.joint_rad  # beyond what a normal run can reach
    call = perturbed.calls[0]
    plain = restroom_scene(doors=call.doors_deg, seats=call.seats_deg)
    assert perturbed.jitter_m > 0 and perturbed.scene_for(call).hash != plain.hash
    assert (
        run.scene_for(run.calls[0]).hash
        == restroom_scene(doors=run.calls[0].doors_deg, seats=run.calls[0].seats_deg).hash
    )
    # The "real" restroom is the same room in every perturbed run.
    other = cleaning_run(12, perturbed=True)
    assert other.scene(call.doors_deg, call.seats_deg).hash == perturbed.scene_for(call).hash


def test_door_angles_per_run(run: CleaningRun, perturbed: CleaningRun) -> None:
    for r in (run, perturbed, cleaning_run(3), cleaning_run(4, perturbed=True)):
        first, last = r.calls[0].doors_deg, r.calls[-1].doors_deg
        assert all(0.0 <= a <= 20.0 for a in first)
        assert all(75.0 <= a <= 90.0 for a in last)
    for r in (perturbed, cleaning_run(4, perturbed=True)):
        angles = r.calls[0].doors_deg + r.calls[-1].doors_deg
        assert all(abs(math.remainder(a, 10.0)) >= 2.0 - TOL for a in angles)
    opened = {cleaning_run(s).calls[-1].doors_deg for s in range(5)}
    assert len(opened) == 5
    fixed = cleaning_run(3, initial_doors_deg=(0, 0, 0), door_open_deg=(90, 90))
    assert fixed.calls[0].doors_deg == (0.0, 0.0, 0.0)
    assert fixed.calls[-1].doors_deg == (90.0, 90.0, 90.0)


def test_motions_repeat(run: CleaningRun) -> None:
    counts = collections.Counter(c.label for c in run.calls)
    repeated = [label for label, n in counts.items() if n >= 3]
    assert len(repeated) >= 10
    assert counts["stall 2: spray_bowl_left → spray_bowl_right"] >= 3
    assert len(counts) < len(run.calls) / 2


def test_scene_changes_during_the_run(run: CleaningRun) -> None:
    doors = [c.doors_deg for c in run.calls]
    seats = [c.seats_deg for c in run.calls]
    assert len(set(doors)) == STALL_COUNT + 1  # initial, then each door opened in turn
    assert len(set(seats)) == STALL_COUNT + 1  # all down, then each seat up once
    assert len(run.events) == 3 * STALL_COUNT
    for event in run.events:
        call = run.calls[event.before_call]
        assert (call.doors_deg, call.seats_deg) == (event.doors_deg, event.seats_deg)
        before = run.calls[event.before_call - 1]
        assert (before.doors_deg, before.seats_deg) != (event.doors_deg, event.seats_deg)
    opening = [e for e in run.events if "door" in e.label]
    for event in opening:  # the door opens right after the arm pushed it
        assert run.calls[event.before_call - 1].label.endswith("→ push_door")


def test_task_configurations_keep_their_clearance(model: RobotModel) -> None:
    """5 cm to the scene (every door angle, seats up or down), 3 cm to the robot itself."""
    lower, upper = np.maximum(model.lower[3:], -np.pi), np.minimum(model.upper[3:], np.pi)
    margin = PERTURBED_NOISE.joint_rad
    scenes = [restroom_scene(doors=d, seats=s) for d in range(0, 91, 5) for s in (0, 90)]
    for kind, tasks in TASKS.items():
        arms = np.array(list(tasks.values()))
        assert np.all((arms >= lower + margin) & (arms <= upper - margin)), kind
        for station in (s for s in work_stations() if s.kind == kind):
            states = np.hstack([np.tile(station.pose, (len(arms), 1)), arms])
            for scene in scenes:
                checker = CollisionChecker(model, scene)
                verdict = checker.check(
                    states,
                    element_pad=np.full((len(states), len(model.elements)), 0.05),
                    pair_pad=np.full((len(states), len(checker.robot.pair_i)), 0.03),
                    stop_at_first=False,
                )
                close = [name for name, v in zip(tasks, verdict.status, strict=True) if v != FREE]
                assert close == [], (station.name, scene.env, close)


def test_routes_name_known_tasks_and_always_move() -> None:
    for kind, route in ROUTES.items():
        moves = ["stow", *(step for step in route if not step.startswith("@"))]
        assert set(moves) <= set(TASKS[kind]), kind
        assert set(TASKS[kind]) <= set(moves), kind  # every configuration is used
        assert all(a != b for a, b in itertools.pairwise(moves)), kind
        assert moves[-1] == "stow"
    assert {OPEN_DOOR, SEAT_UP, SEAT_DOWN} <= set(ROUTES["stall"])
