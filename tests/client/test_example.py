"""examples/robot_loop.py runs against a live service with the reference robot and restroom."""

from __future__ import annotations

import importlib.util
import itertools
import json
import re
from pathlib import Path
from types import ModuleType

import pytest

from tests.client.conftest import LiveServer, make_app
from tests.waiting import NEVER_BINDS_S, SOLVABLE
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import reference_urdf

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "robot_loop.py"


def _load_example() -> ModuleType:
    spec = importlib.util.spec_from_file_location("robot_loop", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_interpolation_bounds_every_step() -> None:
    loop = _load_example()
    steps = loop.interpolate([[0.0, 0.0], [1.0, -0.5], [1.0, -0.5]], max_step=0.05)
    assert steps[0] == [0.0, 0.0] and steps[-1] == [1.0, -0.5]
    gaps = [
        max(abs(b - a) for a, b in zip(p, q, strict=True)) for p, q in itertools.pairwise(steps)
    ]
    assert len(steps) == 22 and max(gaps) <= 0.05 + 1e-12


def test_the_loop_plans_then_serves_the_second_round_from_the_cache(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "robot.urdf").write_text(reference_urdf())
    for name, doors in (("scene.json", (0, 30, 90)), ("scene_door_open.json", (0, 90, 90))):
        payload = scene_to_payload(restroom_scene(doors=doors, seats=(0,)))
        (tmp_path / name).write_text(json.dumps(payload))
    loop = _load_example()
    app = make_app(f"sqlite:///{tmp_path / 'loop.db'}", worker_processes=1, **SOLVABLE)
    with LiveServer(app) as server:
        code = loop.main(
            [
                "--url",
                server.url,
                "--urdf",
                str(tmp_path / "robot.urdf"),
                "--scene",
                str(tmp_path / "scene.json"),
                "--scene-door-open",
                str(tmp_path / "scene_door_open.json"),
                "--budget",
                str(NEVER_BINDS_S),  # every task is planned, however loaded the machine
            ]
        )
    out = capsys.readouterr().out
    assert code == 0, out
    tasks = len(loop.TASKS)
    round_two = [line for line in out.splitlines() if line.startswith("round 2")]
    assert len(round_two) == tasks and all(" cache " in line for line in round_two)
    assert "scene v2" in out  # pushing the door open was sent as a patch
    summary = re.search(r"(\d+) plans from the cache, (\d+) from the planner, 0 without", out)
    assert summary is not None, out
    from_cache, from_planner = int(summary[1]), int(summary[2])
    assert from_cache + from_planner == 2 * tasks and from_cache >= tasks
