"""The plan flow's spine on a real service context (SQLite): each way a request ends, its
bookkeeping through the ordered record writer only, and the time of each phase."""

from __future__ import annotations

import inspect
import math
import threading
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa

from tests.services.hit_setup import context, count_statements, store, two_joint
from tests.waiting import NEVER_BINDS_S
from trajcache.cache.memo import MemoUse
from trajcache.cache.ranking import CandidateFacts
from trajcache.db.models import PlanEvent, Trajectory
from trajcache.geometry.collision.checker import CollisionChecker
from trajcache.geometry.errors import CollisionStateError
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation import validator as validation
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.jobs.backend import Meanwhile, run_meanwhile
from trajcache.planning.problem import PlannerStatus, PlanningProblem, PlanResult
from trajcache.planning.run import run_planning
from trajcache.services.bookkeeping import rejections
from trajcache.services.bookkeeping.records import PlanRecord
from trajcache.services.catalog.robots import put_robot
from trajcache.services.catalog.scene_writes import put_scene
from trajcache.services.context import ServiceContext
from trajcache.services.errors import UnavailableError
from trajcache.services.plan import certified, flow
from trajcache.services.plan.flow import PlanAnswer, PlanRequest, PlanSource, PlanStatus, plan

ARM_PATH = [[0.0, 0.0], [0.3, 0.2], [0.7, 0.2], [1.0, 0.0]]
DETOUR = [[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0]]  # swings back first: through shoulder −0.5
AT = datetime(2030, 1, 2, 3, 4, 5, tzinfo=UTC)


class FakePlanner:
    """A planner pool answering every problem with `result` (after `delay_s`)."""

    def __init__(self, result: PlanResult, delay_s: float = 0.0) -> None:
        self.result = result
        self.delay_s = delay_s
        self.problems: list[PlanningProblem] = []

    def submit(self, problem: PlanningProblem, *, meanwhile: Meanwhile | None = None) -> PlanResult:
        self.problems.append(problem)
        run_meanwhile(meanwhile)  # as a pool does while its worker plans
        time.sleep(self.delay_s)
        return self.result


class Recorded:
    """The records a context's writer receives, in order."""

    def __init__(self, ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch) -> None:
        self.records: list[PlanRecord] = []
        submit = ctx.records.submit

        def spy(record: PlanRecord) -> int:
            self.records.append(record)
            return submit(record)

        monkeypatch.setattr(ctx.records, "submit", spy)


@pytest.fixture
def ctx(tmp_path: Path) -> Iterator[ServiceContext]:
    with context(f"sqlite:///{tmp_path / 'flow.db'}") as service:
        service.records.clock = lambda: AT  # the writer's clock stamps every record
        yield service


def setup_robot(
    ctx: ServiceContext,
    objects: list[dict[str, Any]] | None = None,
    path: list[list[float]] = ARM_PATH,
) -> int:
    """Robot r1 (the two-joint arm) in a scene of `objects`, and one cached trajectory."""
    model = two_joint(ctx)
    with ctx.sessions() as session:
        put_robot(session=session, robot_id="r1", model_id=model.model_id)
        if objects:
            put_scene(
                session=session,
                scenes=ctx.scenes,
                robot_id="r1",
                scene=parse_scene({"objects": objects}),
            )
    return store(ctx, model, path)


def blocker(shoulder: float = -0.5, size: float = 0.04) -> dict[str, Any]:
    """A box in the sweep of the upper arm at `shoulder` (rad)."""
    position = [0.25 * math.sin(shoulder), 0.0, 0.1 + 0.25 * math.cos(shoulder)]
    return {"id": "blocker", "type": "box", "size": [size] * 3, "pose": {"position": position}}


def ask(ctx: ServiceContext, start: list[float], goal: list[float], **options: Any) -> PlanAnswer:
    request = PlanRequest(
        start=np.asarray(start, float),
        goal=np.asarray(goal, float),
        **{"threshold": 0.2, "max_candidates": 3, "fallback": False, **options},
    )
    return plan(ctx=ctx, robot_id="r1", request=request)


def use_planner(ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch, planner: object) -> None:
    monkeypatch.setattr(ctx, "planner_pool", lambda: planner)


def written(ctx: ServiceContext, trajectory_id: int) -> tuple[Trajectory, list[PlanEvent]]:
    """The trajectory's row and every plan event, once the writer has caught up."""
    assert ctx.records.flush(timeout=10)
    with ctx.sessions() as session:
        row = session.get(Trajectory, trajectory_id)
        assert row is not None
        events = list(session.scalars(sa.select(PlanEvent).order_by(PlanEvent.id)))
        session.expunge_all()
    return row, events


def writes(statements: list[str]) -> list[str]:
    """The statements that write usage counters or plan events."""
    return [
        s for s in statements
        if s.lstrip().upper().startswith(("UPDATE", "INSERT INTO PLAN_EVENTS"))
    ]  # fmt: skip


def test_a_hit_is_answered_and_recorded_by_the_writer(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx)
    recorded = Recorded(ctx, monkeypatch)
    ctx.records.linger_s = 30.0  # nothing is written until someone waits
    with count_statements(ctx.engine) as statements:
        answer = ask(ctx, [0.02, 0.0], [0.98, 0.0])
    assert (answer.status, answer.source, answer.trajectory_id) == (
        PlanStatus.SUCCESS, PlanSource.CACHE, stored
    )  # fmt: skip
    assert answer.candidates_tried == 1 and answer.record is not None
    assert not writes(statements)
    [record] = recorded.records
    assert (record.served, record.failed, record.at) == (stored, (), AT)
    assert record.details is None  # nothing rejected: nothing more to work out
    row, events = written(ctx, stored)
    assert (row.hits, row.failures) == (1, 0)
    [event] = events
    assert (event.status, event.source, event.trajectory_id) == ("success", "cache", stored)
    assert event.created_at.replace(tzinfo=UTC) == AT


def test_a_rejected_candidate_then_the_planner(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx, [blocker()], DETOUR)
    recorded = Recorded(ctx, monkeypatch)
    path = np.array([[0.02, 0.0], [0.5, 0.1], [0.98, 0.0]])  # clear of the blocker
    planner = FakePlanner(PlanResult(PlannerStatus.SOLVED, path, seed=7))
    use_planner(ctx, monkeypatch, planner)
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True)
    assert (answer.status, answer.source) == (PlanStatus.SUCCESS, PlanSource.PLANNER)
    assert [r["trajectory_id"] for r in answer.rejected] == [stored]
    assert "blocker" in str(answer.rejected[0]["reason"])
    assert answer.candidates_tried == 1 and np.array_equal(answer.states, path)
    with ctx.sessions() as session, count_statements(ctx.engine) as statements:
        kept = ctx.indexes.states(session, [answer.trajectory_id])  # as its first hit reads them
    assert statements == [] and np.array_equal(kept[answer.trajectory_id], path)
    assert set(ctx.indexes.sizes().values()) == {2}  # indexed when stored, before any sync
    [problem] = planner.problems
    assert problem.start == (0.02, 0.0) and problem.goal == (0.98, 0.0)
    [record] = recorded.records
    assert (record.served, record.failed) == (None, (stored,))
    assert record.quality is not None and record.quality.trajectory_id == answer.trajectory_id
    row, events = written(ctx, stored)
    assert (row.hits, row.failures, row.consecutive_failures) == (0, 1, 1)
    [event] = events
    assert (event.status, event.source, event.seed) == ("success", "planner", 7)
    assert event.trajectory_id == answer.trajectory_id


def test_a_stored_path_s_ranking_facts_are_known_without_a_read(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """This process stored it: its first ranking needs no read of its facts."""
    setup_robot(ctx, [blocker()], DETOUR)
    path = np.array([[0.02, 0.0], [0.5, 0.1], [0.98, 0.0]])
    use_planner(ctx, monkeypatch, FakePlanner(PlanResult(PlannerStatus.SOLVED, path, seed=7)))
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True)
    assert answer.source is PlanSource.PLANNER and answer.trajectory_id is not None
    found, missing = ctx.facts.get_many([answer.trajectory_id])
    assert missing == [] and found[answer.trajectory_id] == CandidateFacts()
    assert ctx.facts.ttl_s == ctx.settings.ranking_facts_ttl_s == 30.0


def test_a_miss_without_planning_is_recorded_by_the_writer(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx, [blocker()], DETOUR)
    recorded = Recorded(ctx, monkeypatch)
    ctx.records.linger_s = 30.0
    with count_statements(ctx.engine) as statements:
        answer = ask(ctx, [0.02, 0.0], [0.98, 0.0])
    assert (answer.status, answer.source, answer.states) == (PlanStatus.MISS, None, None)
    assert answer.message == "no valid cached trajectory; fallback planning disabled"
    assert answer.record is not None and not writes(statements)
    [record] = recorded.records
    assert (record.served, record.failed, record.at) == (None, (stored,), AT)
    row, events = written(ctx, stored)
    assert (row.hits, row.failures) == (0, 1)
    [event] = events
    assert (event.status, event.source, event.candidates_tried) == ("miss", None, 1)
    assert event.error == answer.message


def test_a_rejected_candidate_s_event_names_its_first_failing_sample_link_and_object(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx, [blocker()], DETOUR)
    located: list[str] = []
    locate = rejections.locate_failure

    def spy(*args: Any) -> Any:
        located.append(threading.current_thread().name)
        return locate(*args)

    monkeypatch.setattr(rejections, "locate_failure", spy)
    ctx.records.linger_s = 30.0  # nothing is written until someone waits
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0])
    assert answer.status is PlanStatus.MISS and located == []  # not on the request's path
    _, [event] = written(ctx, stored)
    assert located == ["plan-records"]  # worked out by the record writer
    [rejection] = event.rejections or []
    assert rejection["trajectory_id"] == stored and rejection["status"] == "collision"
    assert rejection["pairs"] == [{"link": "upper", "other": "blocker", "kind": "scene"}]
    assert rejection["start"] == [0.02, 0.0] and rejection["goal"] == [0.98, 0.0]
    assert rejection["reversed"] is False and rejection["segment"] == 0
    # DETOUR swings the shoulder back from 0.02 towards -1: the blocker at -0.5 stops it there
    key = np.array(DETOUR, dtype=float)
    key[0], key[-1] = [0.02, 0.0], [0.98, 0.0]
    model = ctx.models.get(event.model_id)
    assert model is not None
    samples = interpolate(key, model, Resolution())
    assert rejection["samples"] == len(samples)
    failing = np.asarray(rejection["state"])
    assert -0.5 < failing[0] < -0.2  # the upper arm reaches the blocker before its centre
    np.testing.assert_allclose(samples[rejection["sample"]], failing, atol=0.04)


def test_an_endpoint_in_collision_is_refused_before_planning(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx, [blocker(shoulder=1.0, size=0.06)])
    planner = FakePlanner(PlanResult(PlannerStatus.TIMEOUT, message="never asked"))
    use_planner(ctx, monkeypatch, planner)
    with pytest.raises(CollisionStateError, match="goal state is in collision"):
        ask(ctx, [0.0, 0.0], [1.0, 0.0], fallback=True)
    assert not planner.problems


def test_without_a_candidate_the_planner_checks_the_ends_and_a_refused_one_is_named(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx, [blocker(shoulder=1.0, size=0.06)])
    checked: list[int] = []
    contacts = CollisionChecker.state_contacts

    def counted(self: CollisionChecker, state: Any) -> Any:
        checked.append(1)
        return contacts(self, state)

    monkeypatch.setattr(CollisionChecker, "state_contacts", counted)
    refused = FakePlanner(PlanResult(PlannerStatus.INVALID_GOAL, message="goal in collision"))
    use_planner(ctx, monkeypatch, refused)
    with pytest.raises(CollisionStateError, match="goal state is in collision"):
        ask(ctx, [0.0, 0.0], [1.0, 0.0], fallback=True, lookup=False)
    assert len(refused.problems) == 1 and checked  # the planner first, then the contacts
    # free ends, no candidate: the service leaves the ends to the planner
    checked.clear()
    timeout = FakePlanner(PlanResult(PlannerStatus.TIMEOUT, message="nothing found"))
    use_planner(ctx, monkeypatch, timeout)
    answer = ask(ctx, [0.0, 0.0], [-0.3, 0.0], fallback=True, lookup=False)
    assert answer.status is PlanStatus.FAILURE and len(timeout.problems) == 1
    assert not checked
    # a refusal whose end is not in collision stays the planner's failure
    near = FakePlanner(PlanResult(PlannerStatus.INVALID_GOAL, message="goal too near"))
    use_planner(ctx, monkeypatch, near)
    answer = ask(ctx, [0.0, 0.0], [-0.3, 0.0], fallback=True, lookup=False)
    assert answer.status is PlanStatus.FAILURE and "goal too near" in answer.message
    assert len(checked) == 2


def test_the_scene_s_validator_is_built_while_the_planner_plans(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx, [blocker()])
    builders: list[str] = []
    build = validation.build_validator

    def counted(*args: Any, **kwargs: Any) -> Any:
        builders.append("built")
        return build(*args, **kwargs)

    monkeypatch.setattr(validation, "build_validator", counted)
    planner = FakePlanner(PlanResult(PlannerStatus.TIMEOUT, message="nothing found"))
    use_planner(ctx, monkeypatch, planner)
    answer = ask(ctx, [0.0, 0.0], [-0.3, 0.0], fallback=True, lookup=False)
    assert answer.status is PlanStatus.FAILURE  # a failure needs no validator of its own
    assert len(builders) == 1 and len(ctx.validators.validators) == 1  # for the hits to come


def test_a_planner_failure_is_recorded_with_its_seed(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx, [blocker()], DETOUR)
    recorded = Recorded(ctx, monkeypatch)
    result = PlanResult(PlannerStatus.TIMEOUT, message="no path within 0.5 s", seed=11)
    use_planner(ctx, monkeypatch, FakePlanner(result))
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True)
    assert (answer.status, answer.message) == (PlanStatus.FAILURE, "timeout: no path within 0.5 s")
    assert [r.failed for r in recorded.records] == [(stored,)]
    row, events = written(ctx, stored)
    assert row.failures == 1
    [event] = events
    assert (event.status, event.seed, event.error) == ("failure", 11, answer.message)


def test_an_unavailable_planner_is_a_503_whose_event_is_written_first(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    stored = setup_robot(ctx, [blocker()], DETOUR)
    ctx.records.linger_s = 30.0  # written because the flow waits for it, not on its own
    result = PlanResult(PlannerStatus.ERROR, message="worker backend unavailable")
    use_planner(ctx, monkeypatch, FakePlanner(result))
    with pytest.raises(UnavailableError, match="worker backend unavailable"):
        ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True)
    with ctx.sessions() as session:
        assert session.scalars(sa.select(PlanEvent.status)).all() == ["error"]
        row = session.get(Trajectory, stored)
        assert row is not None and row.failures == 1


class SimulatedTime:
    """The `time` module as the phase clock sees it: real time plus simulated waits.

    A wait adds to the clock at once instead of sleeping, so a phase's simulated seconds stand
    out from whatever the real work costs, however loaded the machine is.
    """

    def __init__(self) -> None:
        self.waited_s = 0.0

    def wait(self, seconds: float) -> None:
        """Let `seconds` pass on this clock only."""
        self.waited_s += seconds

    def perf_counter(self) -> float:
        return time.perf_counter() + self.waited_s

    def __getattr__(self, name: str) -> Any:
        return getattr(time, name)


class WaitingPlanner(FakePlanner):
    """A planner pool that answers with `result` after a simulated wait."""

    def __init__(self, result: PlanResult, clock: SimulatedTime, wait_s: float) -> None:
        super().__init__(result)
        self.clock, self.wait_s = clock, wait_s

    def submit(self, problem: PlanningProblem, *, meanwhile: Meanwhile | None = None) -> PlanResult:
        self.clock.wait(self.wait_s)
        return super().submit(problem, meanwhile=meanwhile)


def test_the_clock_gives_each_phase_its_time(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """State checks and validation count as validation, the planner as planning, never as db.

    The waits are simulated (tens of seconds on the phase clock, none in fact), so the real
    lookup and database work, which takes milliseconds, cannot reach the bounds on a busy
    machine.
    """
    setup_robot(ctx, [blocker()], DETOUR)
    clock = SimulatedTime()
    monkeypatch.setattr(inspect.getmodule(flow.PhaseClock), "time", clock)
    check_states, validate_candidate = flow.check_states, flow.validate_candidate

    def slow_check(*args: Any, **kwargs: Any) -> Any:
        clock.wait(20.0)
        return check_states(*args, **kwargs)

    def slow_validate(*args: Any, **kwargs: Any) -> Any:
        clock.wait(50.0)
        return validate_candidate(*args, **kwargs)

    monkeypatch.setattr(flow, "check_states", slow_check)  # start and goal: 40 s
    monkeypatch.setattr(flow, "validate_candidate", slow_validate)  # one candidate: 50 s
    result = PlanResult(PlannerStatus.TIMEOUT, message="no path", seed=1)
    use_planner(ctx, monkeypatch, WaitingPlanner(result, clock, wait_s=60.0))
    timings = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True).timings_ms
    assert set(timings) == {"lookup", "validate", "plan", "db", "total"}
    assert 90_000.0 <= timings["validate"] < 130_000.0
    assert 60_000.0 <= timings["plan"] < 100_000.0
    assert timings["db"] < 40_000.0 and timings["lookup"] < 40_000.0  # none of the waits
    parts = timings["lookup"] + timings["validate"] + timings["plan"] + timings["db"]
    assert parts <= timings["total"] + 0.01


class WorkerPlanner(FakePlanner):
    """A planner pool that runs the worker's own task in this process, then lets `edit` change
    its result; it counts the validations done until it answers."""

    def __init__(self, edit: Any = None) -> None:
        super().__init__(PlanResult(PlannerStatus.ERROR))
        self.edit = edit or (lambda result: result)
        self.validations_before_answer = -1

    def submit(self, problem: PlanningProblem, *, meanwhile: Meanwhile | None = None) -> PlanResult:
        self.problems.append(problem)
        run_meanwhile(meanwhile)
        result = self.edit(run_planning(problem))
        self.validations_before_answer = VALIDATIONS[0]
        return result


VALIDATIONS = [0]


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts every TrajectoryValidator.validate call in this process."""
    VALIDATIONS[0] = 0
    original = TrajectoryValidator.validate

    def validate(self: TrajectoryValidator, key_states: np.ndarray) -> Any:
        VALIDATIONS[0] += 1
        return original(self, key_states)

    monkeypatch.setattr(TrajectoryValidator, "validate", validate)
    return VALIDATIONS


def test_the_worker_s_certificate_stands_for_the_service_s_validation(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch, counted: list[int]
) -> None:
    setup_robot(ctx, [blocker()], DETOUR)
    planner = WorkerPlanner()
    use_planner(ctx, monkeypatch, planner)
    options = {"fallback": True, "max_candidates": 0, "budget_s": NEVER_BINDS_S}
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0], **options)
    assert (answer.status, answer.source) == (PlanStatus.SUCCESS, PlanSource.PLANNER)
    assert planner.validations_before_answer > 0  # the worker certified its path
    assert counted[0] == planner.validations_before_answer  # the service did not again
    # the path is known certified here now, as if the service had validated it
    again = ask(ctx, [0.02, 0.0], [0.98, 0.0], max_candidates=1)
    assert (again.status, again.source) == (PlanStatus.SUCCESS, PlanSource.CACHE)
    assert again.trajectory_id == answer.trajectory_id and again.memo is MemoUse.WHOLE


@pytest.mark.parametrize("edit", ["forged", "moved", "none"])
def test_a_certificate_that_does_not_name_the_path_here_is_validated_again(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch, counted: list[int], edit: str
) -> None:
    setup_robot(ctx, [blocker()], DETOUR)
    through = np.array([[0.02, 0.0], [-1.0, 0.0], [0.98, 0.0]])  # through the blocker

    def change(result: PlanResult) -> PlanResult:
        if edit == "forged":  # a certificate from elsewhere, for a path that collides
            return PlanResult(PlannerStatus.SOLVED, through, certificate="0" * 64)
        if edit == "moved":  # the certified path's certificate, on a colliding path
            return PlanResult(PlannerStatus.SOLVED, through, certificate=result.certificate)
        return PlanResult(PlannerStatus.SOLVED, through)

    use_planner(ctx, monkeypatch, WorkerPlanner(change))
    options = {"fallback": True, "max_candidates": 0, "budget_s": NEVER_BINDS_S}
    answer = ask(ctx, [0.02, 0.0], [0.98, 0.0], **options)
    assert answer.status is PlanStatus.FAILURE
    assert answer.message.startswith("planned path failed validation")
    assert "blocker" in answer.message


def test_a_planned_path_identical_to_a_stored_one_is_not_stored_again(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx)
    path = np.array([[0.02, 0.0], [0.5, 0.1], [0.98, 0.0]])
    use_planner(ctx, monkeypatch, FakePlanner(PlanResult(PlannerStatus.SOLVED, path, seed=7)))
    first = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True, lookup=False)
    again = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True, lookup=False)
    assert (first.source, first.stored) == (PlanSource.PLANNER, True)
    assert (again.source, again.stored) == (PlanSource.PLANNER, False)
    assert again.trajectory_id == first.trajectory_id


def test_a_hit_proves_its_ends_from_the_clearance_measured_after_the_plan(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx, [blocker()], DETOUR)
    path = np.array([[0.02, 0.0], [0.3, 0.1], [0.7, 0.1], [0.98, 0.0]])  # clear of the blocker
    use_planner(ctx, monkeypatch, FakePlanner(PlanResult(PlannerStatus.SOLVED, path, seed=3)))
    planned = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True, max_candidates=0)
    assert planned.source is PlanSource.PLANNER and planned.trajectory_id is not None
    written(ctx, planned.trajectory_id)  # the writer measured its ends, after its quality
    assert len(ctx.end_clearances) == 2
    checked: list[np.ndarray] = []
    validate_segments = TrajectoryValidator.validate_segments

    def spy(self: TrajectoryValidator, key: np.ndarray, segments: list[int]) -> Any:
        checked.append(np.array([key[i : i + 2] for i in segments]))
        return validate_segments(self, key, segments)

    monkeypatch.setattr(TrajectoryValidator, "validate_segments", spy)
    hit = ask(ctx, [0.025, 0.004], [0.975, -0.004], max_candidates=1)
    assert (hit.source, hit.trajectory_id) == (PlanSource.CACHE, planned.trajectory_id)
    assert hit.memo in (MemoUse.ENDS, MemoUse.CERTIFICATE)  # its interior known either way
    assert checked == [] and hit.ends_proved == 1.0  # both proved by the stored ends' clearance
    moved = {**blocker(), "pose": {"position": [0.25 * math.sin(-0.5) + 0.01, 0.0, 0.32]}}
    with ctx.sessions() as session:  # the blocker moved by about a centimetre
        put_scene(session=session, scenes=ctx.scenes, robot_id="r1", scene=parse_scene(
            {"objects": [moved]}))  # fmt: skip
    carried = ask(ctx, [0.024, 0.003], [0.976, -0.003], max_candidates=1)
    assert carried.source is PlanSource.CACHE and carried.trajectory_id == planned.trajectory_id
    assert checked == [] and carried.ends_proved == 1.0  # carried over, less the move
    ctx.end_clearances.clear()
    again = ask(ctx, [0.026, 0.004], [0.974, -0.004], max_candidates=1)
    assert again.source is PlanSource.CACHE and again.memo in (MemoUse.ENDS, MemoUse.CERTIFICATE)
    assert again.ends_proved == 0.0
    ends = np.concatenate(checked)  # without: both new end segments, in full
    assert np.array_equal(ends, [[[0.026, 0.004], [0.3, 0.1]], [[0.7, 0.1], [0.974, -0.004]]])


def test_a_stored_path_s_ends_are_measured_after_its_first_hit(ctx: ServiceContext) -> None:
    """A trajectory this process did not plan (imported, seeded, another replica's) gets its
    end clearances measured by the writer after a hit, for the hits that follow."""
    stored = setup_robot(ctx, [blocker()], ARM_PATH)
    first = ask(ctx, [0.02, 0.0], [0.98, 0.0], max_candidates=1)
    assert (first.source, first.trajectory_id) == (PlanSource.CACHE, stored)
    assert first.ends_proved is None  # validated whole: its ends were not looked up
    assert len(ctx.end_clearances) == 0
    written(ctx, stored)
    assert len(ctx.end_clearances) == 2
    second = ask(ctx, [0.025, 0.004], [0.975, -0.004], max_candidates=1)
    assert (second.source, second.memo) == (PlanSource.CACHE, MemoUse.ENDS)
    assert second.ends_proved == 1.0


def test_a_hit_before_the_writer_measured_a_plan_s_ends_does_not_measure_them_again(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    setup_robot(ctx, [blocker()], DETOUR)
    path = np.array([[0.02, 0.0], [0.3, 0.1], [0.7, 0.1], [0.98, 0.0]])
    use_planner(ctx, monkeypatch, FakePlanner(PlanResult(PlannerStatus.SOLVED, path, seed=3)))
    measured: list[np.ndarray] = []
    go_on = threading.Event()
    measure = certified.measure_clearance

    def held(validator: TrajectoryValidator, segment: np.ndarray) -> Any:
        measured.append(segment.copy())
        go_on.wait(NEVER_BINDS_S)  # the writer measures the plan's ends only after the hit
        return measure(validator, segment)

    monkeypatch.setattr(certified, "measure_clearance", held)
    planned = ask(ctx, [0.02, 0.0], [0.98, 0.0], fallback=True, max_candidates=0)
    hit = ask(ctx, [0.025, 0.004], [0.975, -0.004], max_candidates=1)
    assert (hit.source, hit.trajectory_id) == (PlanSource.CACHE, planned.trajectory_id)
    assert hit.ends_proved == 0.0  # none measured yet
    go_on.set()
    assert planned.trajectory_id is not None
    written(ctx, planned.trajectory_id)
    assert len(measured) == 2 and len(ctx.end_clearances) == 2  # each end once, by the plan's job
    again = ask(ctx, [0.024, 0.003], [0.976, -0.003], max_candidates=1)
    assert again.ends_proved == 1.0


def test_a_hit_is_validated_with_its_reads_ended(
    ctx: ServiceContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The lookup's reads end before validation: their connection closed, and the session's
    transaction (opened to read a model the registry lacks) rolled back."""
    stored = setup_robot(ctx)
    seen: list[tuple[bool, bool]] = []
    validate = flow.validate_candidate

    def spy(attempt: Any, *args: Any) -> Any:
        seen.append((attempt.reads.closed, attempt.session.in_transaction()))
        return validate(attempt, *args)

    monkeypatch.setattr(flow, "validate_candidate", spy)
    for registry_knows in (True, False):
        if not registry_knows:
            ctx.models.clear()  # the model is read in the session, not on the reads' connection
        answer = ask(ctx, [0.02, 0.0], [0.98, 0.0])
        assert (answer.source, answer.trajectory_id) == (PlanSource.CACHE, stored)
    assert seen == [(True, False), (True, False)]
