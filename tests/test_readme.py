"""The README stays true: its settings table, its commands, and its first plan against the app."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tests.client.conftest import LiveServer, make_app
from tests.waiting import SOLVABLE
from trajcache.cli import app as cli_app
from trajcache.cli.docs import TABLE_END, TABLE_START, config_table, with_config_table
from trajcache.core.config import Settings
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import reference_urdf

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def _shell_lines() -> list[str]:
    """Commands of the README's sh blocks, continuation lines joined, comments dropped."""
    lines = []
    for block in _blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split(" #")[0].strip()
            if line and not line.startswith("#"):
                lines.append(line)
    return lines


def test_the_configuration_table_is_generated_from_the_settings() -> None:
    text = README.read_text(encoding="utf-8")
    table = text[text.index(TABLE_START) + len(TABLE_START) : text.index(TABLE_END)]
    assert table.strip() == config_table().strip(), (
        "the README's configuration table is stale; run `trajcache config-table --readme README.md`"
    )


def test_the_table_has_every_setting_with_its_default_and_meaning() -> None:
    rows = {row.split("|")[1].strip(" `"): row for row in config_table().splitlines()[2:]}
    assert len(rows) == len(Settings.model_fields)
    for name, field in Settings.model_fields.items():
        assert field.description, f"setting {name} has no description for the README"
        row = rows[f"TRAJCACHE_{name.upper()}"]
        assert " ".join(field.description.split()).replace("|", "\\|") in row
    assert "| `TRAJCACHE_PORT` | `8000` |" in config_table()
    assert "| `TRAJCACHE_CERTIFIED_VALIDATION` | `true` |" in config_table()


def test_the_config_table_command_updates_and_checks(tmp_path: Path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n\n{TABLE_START}\n| stale |\n{TABLE_END}\n\nafter\n")
    runner = CliRunner()
    stale = runner.invoke(cli_app, ["config-table", "--readme", str(readme), "--check"])
    assert stale.exit_code == 1 and "trajcache config-table --readme" in stale.output
    assert runner.invoke(cli_app, ["config-table", "--readme", str(readme)]).exit_code == 0
    text = readme.read_text()
    assert text.startswith("# x\n\n") and text.endswith(f"{TABLE_END}\n\nafter\n")
    assert config_table() in text and "| stale |" not in text
    fresh = runner.invoke(cli_app, ["config-table", "--readme", str(readme), "--check"])
    assert fresh.exit_code == 0
    printed = runner.invoke(cli_app, ["config-table"])
    assert printed.output == config_table()


def test_a_readme_without_markers_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="config-table"):
        with_config_table("# no table here\n")
    readme = tmp_path / "README.md"
    readme.write_text("# no table here\n")
    result = CliRunner().invoke(cli_app, ["config-table", "--readme", str(readme)])
    assert result.exit_code == 2 and readme.read_text() == "# no table here\n"


def test_every_command_in_the_readme_exists() -> None:
    runner = CliRunner()
    invoked = [
        line.split("trajcache ", 1)[1].split()
        for line in _shell_lines()
        if re.match(r"^(\.venv/bin/)?trajcache ", line)
        or re.search(r"\brun --rm \w+ trajcache ", line)
    ]
    assert {args[0] for args in invoked} >= {"reference", "migrate", "serve", "worker", "openapi"}
    for args in invoked:
        words = [a for a in args if not a.startswith("…") and a != "--help"]
        result = runner.invoke(cli_app, [*words, "--help"])
        assert result.exit_code == 0, f"`trajcache {' '.join(args)}`: {result.output}"
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M))
    used = set(re.findall(r"`make ([\w-]+)`", README.read_text())) | {
        line.split()[1] for line in _shell_lines() if line.startswith("make ")
    }
    assert used and used <= targets


def _documents(text: str) -> list[dict[str, object]]:
    """The JSON documents printed one after another (curl adds no newlines)."""
    decoder, found, at = json.JSONDecoder(), [], 0
    while at < len(text.rstrip()):
        document, at = decoder.raw_decode(text, at)
        found.append(document)
    return found


@pytest.fixture
def first_plan_dir(tmp_path: Path) -> Path:
    """A directory holding what the README's first two commands write."""
    (tmp_path / "robot.urdf").write_text(reference_urdf())
    scene = scene_to_payload(restroom_scene(doors=(0, 30, 90), seats=(0,)))
    (tmp_path / "scene.json").write_text(json.dumps(scene, indent=1))
    return tmp_path


def test_the_first_plan_with_curl_works_as_written(first_plan_dir: Path) -> None:
    if shutil.which("curl") is None or shutil.which("bash") is None:
        pytest.skip("curl and bash are needed to run the README's shell commands")
    (block,) = [b for b in _blocks("sh") if "curl" in b and "/plan" in b]
    app = make_app(f"sqlite:///{first_plan_dir / 'readme.db'}", worker_processes=1, **SOLVABLE)
    with LiveServer(app) as server:
        script = block.replace("localhost:8000", server.url.removeprefix("http://"))
        run = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", script],
            cwd=first_plan_dir,
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert run.returncode == 0, run.stderr
    robot, scene, plan = _documents(run.stdout)
    assert robot["robot_id"] == "r1" and scene["version"] == 1
    assert plan["status"] == "success" and plan["source"] == "planner"
    assert plan["trajectory_id"] == 1


def _run(code: str, url: str) -> None:
    exec(compile(code.replace("http://127.0.0.1:8000", url), "README", "exec"), {})


def test_the_python_client_examples_work_as_written(
    first_plan_dir: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    first_plan, blocking, asyncio_ = [b for b in _blocks("python") if "trajcache_client" in b]
    assert "register_model" in first_plan and "AsyncClient" in asyncio_
    monkeypatch.chdir(first_plan_dir)
    app = make_app(f"sqlite:///{first_plan_dir / 'readme.db'}", worker_processes=1, **SOLVABLE)
    with LiveServer(app) as server:
        _run(first_plan, server.url)
        there, back = capsys.readouterr().out.splitlines()
        assert there.startswith("success planner 1 ") and back.startswith("success cache 1 ")
        assert app.state.ctx.records.flush(timeout=30)  # the plan events are written
        _run(blocking, server.url)
        totals, *events = capsys.readouterr().out.splitlines()
        assert totals == "2 1 0.5"
        assert [e.split()[:3] for e in events] == [
            ["success", "cache", "1"],
            ["success", "planner", "1"],
        ]
        _run(asyncio_, server.url)
        assert capsys.readouterr().out.splitlines() == ["success cache 1"] * 2
