"""A robot controller loop on trajcache: keep the scene current, plan, execute.

Against a local service (`make serve`) and the reference robot, from the repository root:

    .venv/bin/trajcache reference robot --out robot.urdf
    .venv/bin/trajcache reference scene --doors 0,30,90 --out scene.json
    .venv/bin/trajcache reference scene --doors 0,90,90 --out scene_door_open.json
    .venv/bin/python examples/robot_loop.py

The robot drives to stall 2 and works there; pushing the door opens it (the world switches to
`scene_door_open.json`). Before every plan the loop sends what changed in the world since the
last upload (a PATCH of the objects that moved) and then executes the answer by stepping through
interpolated states, as a controller feeding its drives would. The second round is served from
the cache the first one filled.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from trajcache_client import Client, ConflictError, NotFoundError, PlanResult

State = list[float]
STOW = [0.0, -1.3, 0.0, 0.8, 0.0, 2.1, 0.0]
AISLE = [0.925, 1.05, 0.0]  # base pose x, y, θ between stalls 1 and 2
STALL_2 = [1.375, 1.3, math.pi / 2]  # base pose in front of stall 2
# (task, goal state, world after the move): arm configurations of the reference robot.
TASKS: list[tuple[str, State, str]] = [
    ("drive to stall 2", [*STALL_2, *STOW], "closed"),
    ("reach handle", [*STALL_2, 0.736, -0.828, -0.968, 1.062, 0.341, 0.076, 0.0], "closed"),
    ("push door", [*STALL_2, 1.161, -0.821, -1.352, 1.062, 0.214, -0.356, 0.0], "open"),
    ("stow", [*STALL_2, *STOW], "open"),
    ("spray rim", [*STALL_2, 0.0, -0.876, 0.0, 1.483, 0.0, 1.252, 0.0], "open"),
    ("spray bowl", [*STALL_2, 0.491, -1.424, 0.487, 0.766, -0.391, 1.272, 0.0], "open"),
    ("stow", [*STALL_2, *STOW], "open"),
    ("back to the aisle", [*AISLE, *STOW], "open"),
]


class SceneSync:
    """Keeps the service's copy of a robot's scene equal to the world the robot perceives."""

    def __init__(self, client: Client, robot_id: str) -> None:
        self.client, self.robot_id = client, robot_id
        self.sent: dict[str, Any] | None = None

        self.version = 0

    def sync(self, world: dict[str, Any]) -> int:
        """Send what changed since the last upload (everything the first time); the version."""
        world = {"objects": world.get("objects", []), "env": world.get("env", {})}
        if self.sent is None:
            return self._replace(world)
        before = {o["id"]: o for o in self.sent["objects"]}
        after = {o["id"]: o for o in world["objects"]}
        upsert = [o for oid, o in after.items() if before.get(oid) != o]
        remove = [oid for oid in before if oid not in after]
        env: dict[str, float | None] = {
            k: v for k, v in world["env"].items() if self.sent["env"].get(k) != v
        }
        env.update({k: None for k in self.sent["env"] if k not in world["env"]})
        if not (upsert or remove or env):
            return self.version
        try:
            patched = self.client.patch_scene(self.robot_id, upsert=upsert, remove=remove, env=env)
        except (ConflictError, NotFoundError):  # changed under us: send it whole
            return self._replace(world)
        self.sent, self.version = world, patched.version
        return self.version

    def _replace(self, world: dict[str, Any]) -> int:
        self.sent, self.version = world, self.client.put_scene(self.robot_id, world).version
        return self.version


def interpolate(states: Sequence[State], max_step: float) -> list[State]:
    """The states a controller sends: straight lines between key states, steps ≤ max_step."""
    out = [list(states[0])]
    for a, b in itertools.pairwise(states):
        gap = max(abs(y - x) for x, y in zip(a, b, strict=True))
        n = max(1, math.ceil(gap / max_step))
        out += [[x + (y - x) * i / n for x, y in zip(a, b, strict=True)] for i in range(1, n + 1)]
    return out


def execute(states: Sequence[State], drive_fn: Callable[[State], None], period_s: float) -> State:
    """Step through the interpolated states (simulated: `drive_fn` records or prints them)."""
    for state in interpolate(states, max_step=0.05):
        drive_fn(state)
        if period_s > 0:
            time.sleep(period_s)
    return list(states[-1])


def run(client: Client, args: argparse.Namespace) -> dict[str, int]:
    """Register the robot, then run the task list `args.rounds` times; counts by answer source."""
    urdf = Path(args.urdf).read_text(encoding="utf-8")
    worlds = {
        "closed": json.loads(Path(args.scene).read_text(encoding="utf-8")),
        "open": json.loads(Path(args.scene_door_open).read_text(encoding="utf-8")),
    }
    model = client.register_model(urdf, base="planar", name="reference")
    client.put_robot(args.robot, model.model_id)
    scene = SceneSync(client, args.robot)
    state: State = [*AISLE, *STOW]
    world = "closed"
    counts = {"cache": 0, "planner": 0, "failed": 0, "steps": 0}

    def drive(command: State) -> None:
        counts["steps"] += 1

    for round_no in range(1, args.rounds + 1):
        world = "closed"  # a new round: the door has swung shut again
        for task, goal, world_after in TASKS:
            version = scene.sync(worlds[world])
            answer: PlanResult = client.plan(args.robot, state, goal, {"budget_s": args.budget})
            if not answer.ok or answer.states is None:
                counts["failed"] += 1
                print(f"round {round_no} {task:<18} {answer.status}: {answer.message}")
                continue
            counts[str(answer.source)] += 1
            state = execute(answer.states, drive, args.period)
            world = world_after
            total = answer.timings_ms.get("total", 0.0)
            print(
                f"round {round_no} {task:<18} scene v{version:<3} {answer.source:<7} "
                f"trajectory {answer.trajectory_id:<5} {len(answer.states):>3} key states "
                f"{total:7.1f} ms"
            )
    return counts


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the arguments, run the loop, print a summary; 1 when a task found no trajectory."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000", help="The service.")
    parser.add_argument("--api-key", default=None, help="An API key, when the service needs one.")
    parser.add_argument("--robot", default="robot-1", help="This robot's id.")
    parser.add_argument("--urdf", default="robot.urdf")
    parser.add_argument("--scene", default="scene.json", help="The world with the door shut.")
    parser.add_argument("--scene-door-open", default="scene_door_open.json")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--budget", type=float, default=5.0, help="Planning budget (s).")
    parser.add_argument("--period", type=float, default=0.0, help="Seconds per control step.")
    args = parser.parse_args(argv)
    with Client(args.url, api_key=args.api_key) as client:
        counts = run(client, args)
    print(
        f"{counts['cache']} plans from the cache, {counts['planner']} from the planner, "
        f"{counts['failed']} without a trajectory; {counts['steps']} control steps executed"
    )
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
