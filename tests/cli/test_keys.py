"""`trajcache keys`: create, list (times whole, whatever the terminal width) and revoke once."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trajcache.cli import app

# ISO 8601 to the second with the offset: nothing of a time may be cut or folded away.
TIME = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")


@pytest.fixture
def runner(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """A CLI runner on a fresh SQLite database and an 80-column terminal."""
    monkeypatch.setenv("TRAJCACHE_DATABASE_URL", f"sqlite:///{tmp_path / 'keys.db'}")
    monkeypatch.setenv("COLUMNS", "80")
    return CliRunner()


def _create(runner: CliRunner, *args: str) -> str:
    made = runner.invoke(app, ["keys", "create", *args])
    assert made.exit_code == 0, made.output
    secret = made.stdout.strip().splitlines()[-1]
    assert secret.startswith("tc_")
    return secret


def test_cli_creates_lists_and_revokes_keys(runner: CliRunner) -> None:
    secret = _create(runner, "--name", "forklift-7", "--role", "robot", "--robot", "r1")
    listed = runner.invoke(app, ["keys", "list"])
    assert listed.exit_code == 0 and "forklift-7" in listed.stdout and secret not in listed.stdout
    prefix = secret.split("_")[1]
    assert runner.invoke(app, ["keys", "revoke", prefix]).exit_code == 0
    assert "forklift-7" not in runner.invoke(app, ["keys", "list"]).stdout
    assert "forklift-7" in runner.invoke(app, ["keys", "list", "--all"]).stdout
    bad = runner.invoke(app, ["keys", "create", "--name", "x", "--role", "root"])
    assert bad.exit_code == 2 and "'root' is not one of" in bad.output  # a usage error


def test_revoking_a_revoked_key_fails_and_says_so(runner: CliRunner) -> None:
    prefix = _create(runner, "--name", "ops", "--role", "admin").split("_")[1]
    assert runner.invoke(app, ["keys", "revoke", prefix]).exit_code == 0
    again = runner.invoke(app, ["keys", "revoke", prefix])
    assert again.exit_code == 2, again.output
    message = " ".join(again.stderr.split())  # the error console wraps at the terminal width
    assert re.search(rf"#1 \({prefix}, 'ops'\) was already revoked at {TIME.pattern}", message)
    missing = runner.invoke(app, ["keys", "revoke", "nope"])
    assert missing.exit_code == 2 and "'nope' not found" in missing.stderr


def test_list_prints_times_whole_on_a_narrow_terminal(runner: CliRunner) -> None:
    robots = [arg for i in range(12) for arg in ("--robot", f"warehouse-robot-{i}")]
    _create(
        runner, "--name", "a key for every robot of the east warehouse", "--role", "robot", *robots
    )
    prefix = _create(runner, "--name", "ops", "--role", "admin").split("_")[1]
    assert runner.invoke(app, ["keys", "revoke", prefix]).exit_code == 0
    listed = runner.invoke(app, ["keys", "list", "--all"])
    assert listed.exit_code == 0, listed.output
    assert len(TIME.findall(listed.stdout)) == 3, listed.stdout  # two created, one revoked
    assert "warehouse-robot-11" in listed.stdout and "…" not in listed.stdout


def test_create_and_revoke_say_whether_keys_are_required_and_how_to_turn_it_off(
    runner: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = runner.invoke(app, ["keys", "create", "--name", "ops", "--role", "admin"])
    note = " ".join(made.stderr.split())
    assert "the service now requires an API key on every /v1 request" in note
    assert "TRAJCACHE_AUTH_MODE=off" in note
    first = made.stdout.strip().splitlines()[-1].split("_")[1]
    second = _create(runner, "--name", "seed", "--role", "seeder").split("_")[1]
    revoked = " ".join(runner.invoke(app, ["keys", "revoke", first]).stderr.split())
    assert "1 active key(s) left; the service still requires keys" in revoked
    last = " ".join(runner.invoke(app, ["keys", "revoke", second]).stderr.split())
    assert "no active key is left, and the service still requires one" in last
    assert "`trajcache keys create`" in last and "TRAJCACHE_AUTH_MODE=off" in last
    monkeypatch.setenv("TRAJCACHE_AUTH_MODE", "off")
    made = runner.invoke(app, ["keys", "create", "--name", "later", "--role", "admin"])
    assert "key checks are off here (TRAJCACHE_AUTH_MODE=off)" in " ".join(made.stderr.split())
