"""`trajcache reference robot|scene` through the real Typer app."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import pytest
import yaml
import yourdfpy
from typer.testing import CliRunner

from trajcache.cli import app
from trajcache.geometry.scene.parse import load_scene_text, parse_scene
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import reference_urdf

runner = CliRunner()


def test_robot_to_stdout_and_file(tmp_path: Path) -> None:
    result = runner.invoke(app, ["reference", "robot"])
    assert result.exit_code == 0, result.output
    assert result.stdout == reference_urdf()
    urdf = yourdfpy.URDF.load(io.StringIO(result.stdout), load_meshes=False)
    assert len(urdf.actuated_joint_names) == 7
    out = tmp_path / "robot.urdf"
    result = runner.invoke(app, ["reference", "robot", "--out", str(out)])
    assert result.exit_code == 0 and result.stdout == ""
    assert out.read_text() == reference_urdf()


def test_scene_json_default_matches_generator() -> None:
    result = runner.invoke(app, ["reference", "scene", "--doors", "0,30,90", "--seats", "0"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.stdout)
    scene = parse_scene(payload)
    assert scene.hash == restroom_scene(doors=[0, 30, 90], seats=0).hash
    assert scene.env["stall_2_door"] == pytest.approx(math.radians(30))


def test_scene_yaml_and_moveit_formats(tmp_path: Path) -> None:
    expected = restroom_scene(doors=45, seats=[0, 90, 0])
    args = ["reference", "scene", "--doors", "45", "--seats", "0,90,0"]
    result = runner.invoke(app, [*args, "--format", "yaml"])
    assert result.exit_code == 0, result.output
    assert parse_scene(yaml.safe_load(result.stdout)).hash == expected.hash
    out = tmp_path / "scene.json"
    result = runner.invoke(app, [*args, "--format", "moveit", "--out", str(out)])
    assert result.exit_code == 0, result.output
    message = json.loads(out.read_text())
    objects = message["world"]["collision_objects"]
    assert {o["header"]["frame_id"] for o in objects} == {"world"}
    assert len(objects) == len(expected.objects)
    # MoveIt carries no env values; the geometry is the same
    from_text = parse_scene(load_scene_text(out.read_text()))
    assert [o.id for o in from_text.objects] == [o.id for o in expected.objects]
    assert from_text.env == {}
    assert parse_scene({**message, "env": expected.env}).hash == expected.hash


def test_scene_jitter_is_seeded() -> None:
    args = ["reference", "scene", "--seed", "3", "--jitter", "0.02"]
    first, second = runner.invoke(app, args), runner.invoke(app, args)
    assert first.exit_code == 0 and first.stdout == second.stdout
    assert parse_scene(json.loads(first.stdout)).hash == restroom_scene(seed=3, jitter_m=0.02).hash


@pytest.mark.parametrize("doors", ["0,90", "abc", "120"])
def test_scene_rejects_bad_angles(doors: str) -> None:
    result = runner.invoke(app, ["reference", "scene", "--doors", doors])
    assert result.exit_code == 2
    assert "Invalid value" in result.output


def test_help_lists_reference_commands() -> None:
    result = runner.invoke(app, ["reference", "--help"])
    assert result.exit_code == 0
    assert "robot" in result.output and "scene" in result.output
