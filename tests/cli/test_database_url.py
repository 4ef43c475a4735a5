"""Commands that touch the database work on the one given with `--database-url`."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from typer.testing import CliRunner

from trajcache.cli import app


@pytest.fixture
def other_db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A migrated SQLite database that is not the configured one (which must stay untouched)."""
    configured = tmp_path / "configured.db"
    monkeypatch.setenv("TRAJCACHE_DATABASE_URL", f"sqlite:///{configured}")
    url = f"sqlite:///{tmp_path / 'other.db'}"
    result = CliRunner().invoke(app, ["migrate", "--database-url", url])
    assert result.exit_code == 0, result.output
    assert not configured.exists()
    return url


def _key_names(url: str) -> list[str]:
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            return [row[0] for row in conn.execute(sa.text("SELECT name FROM api_keys"))]
    finally:
        engine.dispose()


def test_keys_work_on_the_given_database(other_db: str, tmp_path: Path) -> None:
    runner = CliRunner()
    created = runner.invoke(
        app, ["keys", "create", "--name", "ops", "--role", "admin", "--database-url", other_db]
    )
    assert created.exit_code == 0, created.output
    assert _key_names(other_db) == ["ops"]
    listed = runner.invoke(app, ["keys", "list", "--database-url", other_db])
    assert listed.exit_code == 0 and "ops" in listed.output
    revoked = runner.invoke(app, ["keys", "revoke", "1", "--database-url", other_db])
    assert revoked.exit_code == 0, revoked.output
    assert not (tmp_path / "configured.db").exists()


def test_a_role_outside_the_choices_is_a_usage_error(other_db: str) -> None:
    result = CliRunner().invoke(
        app, ["keys", "create", "--name", "x", "--role", "root", "--database-url", other_db]
    )
    assert result.exit_code == 2
    assert "robot" in result.output and "seeder" in result.output


def test_transfer_commands_work_on_the_given_database(other_db: str, tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "cache.jsonl"
    exported = runner.invoke(app, ["export", "--out", str(out), "--database-url", other_db])
    assert exported.exit_code == 0, exported.output
    imported = runner.invoke(app, ["import", str(out), "--database-url", other_db])
    assert imported.exit_code == 0, imported.output
    pruned = runner.invoke(
        app, ["prune", "--cap", "5", "--policy", "lru", "--database-url", other_db]
    )
    assert pruned.exit_code == 0, pruned.output
    assert not (tmp_path / "configured.db").exists()
