"""Planning until a path is certified: repair, search again, and say why when none is.

Certification is scripted here: a validator that rejects, as too close to certify, every motion
through a region of the state space the planners' sample checks do not see (as distance bounds
that cannot prove a near-contact motion free), so that the sample-checked straight path fails.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from tests.robots import TWO_ROD_URDF
from tests.waiting import NEVER_BINDS_S
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.validator import (
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
    interpolate,
)
from trajcache.planning import attempts, ompl_planner, rris
from trajcache.planning.deadline import Deadline
from trajcache.planning.ompl_planner import plan_ompl
from trajcache.planning.options import SearchOptions
from trajcache.planning.problem import PlannerStatus, PlanResult
from trajcache.planning.rris import plan_with_rris

START, GOAL = np.array([-1.0, 0.0]), np.array([1.0, 0.0])  # the straight path is free
FOG, FOG_RADIUS = np.array([0.0, 0.0]), 0.3  # on the straight path, away from both ends
PLANNERS: dict[str, Callable[..., PlanResult]] = {"rrtconnect": plan_ompl, "rris": plan_with_rris}


def fogged(reject: Callable[[np.ndarray], bool]) -> type[TrajectoryValidator]:
    """A validator that also rejects, as too close to certify, paths whose samples `reject`."""

    class Fogged(TrajectoryValidator):
        def validate(self, key_states: np.ndarray) -> ValidationResult:
            result = super().validate(key_states)
            samples = interpolate(np.asarray(key_states), self.model, self.resolution)
            if result.valid and reject(samples):
                why = "the motion passes closer than can be certified (fog)"
                return ValidationResult(ValidationStatus.TOO_CLOSE, len(samples), 0, message=why)
            return result

    return Fogged


def in_fog(samples: np.ndarray) -> bool:
    return bool(np.any(np.linalg.norm(samples - FOG, axis=1) < FOG_RADIUS))


def moving(samples: np.ndarray) -> bool:
    return bool(np.ptp(samples, axis=0).max() > 0.0)


@pytest.fixture
def empty() -> Scene:
    return make_scene([])


@pytest.fixture(params=sorted(PLANNERS))
def planner(request: pytest.FixtureRequest) -> Callable[..., PlanResult]:
    return PLANNERS[request.param]


def use(monkeypatch: pytest.MonkeyPatch, reject: Callable[[np.ndarray], bool]) -> None:
    for module in (ompl_planner, rris):
        monkeypatch.setattr(module, "TrajectoryValidator", fogged(reject))


def test_a_path_that_fails_certification_is_repaired(
    planner: Callable[..., PlanResult], empty: Scene, monkeypatch: pytest.MonkeyPatch
) -> None:
    use(monkeypatch, in_fog)
    model = load_robot_model(TWO_ROD_URDF, base="fixed")
    result = planner(
        model, empty, START, GOAL, options=SearchOptions(budget_s=NEVER_BINDS_S, seed=0)
    )
    assert result.status is PlannerStatus.SOLVED, result.message
    assert result.path is not None and np.allclose(result.path[[0, -1]], [START, GOAL])
    assert not in_fog(interpolate(result.path, model, TrajectoryValidator(model, empty).resolution))
    assert result.stats["repairs"] >= 1 and result.stats["attempts"] == 1


def test_no_certifiable_path_spends_the_budget_and_says_so(
    planner: Callable[..., PlanResult], empty: Scene, monkeypatch: pytest.MonkeyPatch
) -> None:
    use(monkeypatch, moving)  # nothing that moves is certified
    monkeypatch.setattr(attempts, "REPAIR_S", 0.1)
    model = load_robot_model(TWO_ROD_URDF, base="fixed")
    budgets: list[Deadline] = []

    def recorded(budget_s: float) -> Deadline:
        budgets.append(Deadline(budget_s))
        return budgets[-1]

    for module in (ompl_planner, rris):
        monkeypatch.setattr(module, "Deadline", recorded)
    result = planner(model, empty, START, GOAL, options=SearchOptions(budget_s=0.8, seed=0))
    assert result.status is PlannerStatus.UNCERTIFIED and result.path is None
    assert result.message.startswith("no certifiable path within the budget")
    assert "closer than can be certified (fog)" in result.message
    assert result.stats["attempts"] >= 2  # it searched again after a repair failed
    assert [b.budget_s for b in budgets] == [0.8] and budgets[0].expired()  # it spent it all


def test_an_endpoint_no_motion_can_leave_certified_fails_at_its_first_path(
    planner: Callable[..., PlanResult], empty: Scene, monkeypatch: pytest.MonkeyPatch
) -> None:
    # as a real one: no motion that reaches GOAL (nor a stay there) is certified
    use(monkeypatch, lambda samples: bool(np.all(np.isclose(samples, GOAL), axis=1).any()))
    model = load_robot_model(TWO_ROD_URDF, base="fixed")
    result = planner(model, empty, START, GOAL, options=SearchOptions(budget_s=5.0, seed=0))
    # asked once the first path was rejected: no repair, no second search
    assert result.stats["attempts"] == 1 and result.stats["repairs"] == 0
    assert result.status is PlannerStatus.INVALID_GOAL
    assert result.message.startswith("no motion to the goal can be certified")


def test_without_any_path_it_is_a_timeout(planner: Callable[..., PlanResult]) -> None:
    model = load_robot_model(TWO_ROD_URDF, base="fixed")
    post = np.eye(4)
    post[:3, 3] = (0.25, 0.0, 0.5)  # on the upper arm's way: no elbow angle gets past
    scene = make_scene([SceneObject("post", Shape(ShapeKind.BOX, (0.1, 0.1, 1.0)), post)])
    result = planner(model, scene, START, GOAL, options=SearchOptions(budget_s=0.3, seed=0))
    assert result.status is PlannerStatus.TIMEOUT, result.message
    assert result.stats["paths_found"] == 0
