"""What `trajcache demo` plays: the reference cleaning runs through running services.

Only package code: services are started by `trajcache.cli.launch`, the robot talks to them
with the client library (`trajcache_client`), and every returned trajectory is re-checked here,
outside the service, with the package's validator sampling 4× finer than the service's steps
in the scene in force at its call. The paper protocol's full harness (paired baselines,
PostgreSQL, the independent FCL dense check, the paper's figures and the chart) lives in
`bench/` (`python bench/paper_tables.py`), which is not installed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator
from trajcache.reference import (
    REFERENCE_BASE,
    REFERENCE_NAME,
    STOWED_ARM,
    CleaningRun,
    cleaning_run,
    door_sweep_run,
    reference_model,
    reference_urdf,
)
from trajcache_client import Client

FINER = Resolution(0.01, 0.01, 0.00875)  # the service's default steps / 4
OPTIONS: dict[str, dict[str, Any]] = {
    "none": {"fallback": True, "lookup": False},
    "full": {"fallback": True, "match": "full"},
    "arm": {"fallback": True, "match": "arm"},
}
WARM_UP = [-20.0, -20.0, 0.0, *STOWED_ARM]  # far outside the restroom


@dataclass(frozen=True)
class DemoRow:
    """One row: a run played against one cache; `real` rows are the perturbed restroom."""

    key: str
    table: int
    label: str
    cache: str
    run: Callable[[], CleaningRun]

    @property
    def options(self) -> str:
        """Plan options: "none" (every call planned), "arm" or "full" matching."""
        return "none" if self.cache == "none" else "arm" if self.key.endswith("_arm") else "full"

    @property
    def baseline(self) -> str:
        """The no-cache row the speed-up divides."""
        return "real_none" if self.key.startswith("real") else "sim_none"


@dataclass
class RowResult:
    """What a row's calls got: counts and the service's own time (sum of timings_ms total)."""

    row: DemoRow
    calls: int = 0
    hits: int = 0
    planned: int = 0
    failed: int = 0
    checked: int = 0
    collisions: int = 0
    service_ms: float = 0.0
    messages: list[str] = field(default_factory=list)


def demo_rows(*, seed: int, doors: tuple[int, ...], arm: bool) -> list[DemoRow]:
    """The rows in the order they are played (the paper protocol's, + rows beyond it)."""
    run1, run2 = (lambda: cleaning_run(seed)), (lambda: cleaning_run(seed + 1))
    real = lambda: cleaning_run(seed + 2, perturbed=True)  # noqa: E731
    real2 = lambda: cleaning_run(seed + 3, perturbed=True)  # noqa: E731
    rows = [
        DemoRow("sim_none", 1, "no cache", "none", run1),
        DemoRow("run1", 1, "run 1, empty cache", "sim", run1),
        DemoRow("run2", 1, "run 2, cache of run 1", "sim", run2),
        DemoRow("run1_arm", 1, "+ run 1, empty cache, match=arm", "sim_arm", run1),
        DemoRow("run2_arm", 1, "+ run 2, cache of run 1, match=arm", "sim_arm", run2),
        *(
            DemoRow(f"sweep_{d}", 2, f"simulation, doors {d}°", "seeded", _sweep(d, seed))
            for d in doors
        ),
        DemoRow("real_none", 2, "real (a), no cache", "none", real),
        DemoRow("real_empty", 2, "real (b), empty cache", "real", real),
        DemoRow("real_empty_arm", 2, "+ real (b), empty cache, match=arm", "real_arm", real),
        DemoRow("real_seeded", 2, "real (c), pre-seeded cache", "seeded", real),
        DemoRow("real_second", 2, "real (d), second run on (c)", "seeded", real2),
    ]
    return [r for r in rows if arm or not r.label.startswith("+ ")]


def _sweep(deg: int, seed: int) -> Callable[[], CleaningRun]:
    return lambda: door_sweep_run(float(deg), seed)


def prepare(client: Client) -> str:
    """Register the reference model, plan and hit once far away, empty the cache; the model id."""
    model_id = client.register_model(
        reference_urdf(), base=REFERENCE_BASE, name=REFERENCE_NAME
    ).model_id
    client.put_robot("warm-up", model_id, kind="sim")
    client.put_scene("warm-up", {"objects": [], "env": {}})
    for d in (0.5, 0.49):
        goal = [*WARM_UP[:3], WARM_UP[3] + d, *WARM_UP[4:]]
        client.plan("warm-up", WARM_UP, goal, {"fallback": True})
    for item in client.list_trajectories(model_id=model_id, limit=100).items:
        client.delete_trajectory(item.trajectory_id)
    return model_id


class Checker:
    """Re-checks returned trajectories in the scene of their call, 4× finer than the service."""

    def __init__(self) -> None:
        self.model = reference_model()
        self._validators: dict[str, TrajectoryValidator] = {}

    def collides(self, states: list[list[float]], scene: Scene) -> bool:
        """Whether the trajectory through `states` is found in collision or beyond a limit."""
        validator = self._validators.get(scene.hash)
        if validator is None:
            validator = TrajectoryValidator(self.model, scene, resolution=FINER, certified=False)
            self._validators[scene.hash] = validator
        return not validator.validate(np.asarray(states, dtype=float)).valid


def play_row(
    client: Client, model_id: str, row: DemoRow, calls: int | None, checker: Checker
) -> RowResult:
    """Play the row's run as robot `row.key` (scene kept current), checking every answer."""
    run, result = row.run(), RowResult(row)
    robot = row.key.replace("_", "-")
    client.put_robot(robot, model_id, kind="real" if row.key.startswith("real") else "sim")
    shown = ""
    for call in run.calls[:calls]:
        scene = run.scene_for(call)
        if scene.hash != shown:
            client.put_scene(robot, scene_to_payload(scene))
            shown = scene.hash
        answer = client.plan(robot, call.start.tolist(), call.goal.tolist(), OPTIONS[row.options])
        result.calls += 1
        result.service_ms += float(answer.timings_ms.get("total", 0.0))
        if not answer.ok or answer.states is None:
            result.failed += 1
            result.messages.append(f"call {call.index}: {answer.status} {answer.message}")
            continue
        result.hits += answer.source == "cache"
        result.planned += answer.source == "planner"
        result.checked += 1
        result.collisions += checker.collides(answer.states, scene)
    return result
