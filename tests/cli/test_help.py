"""Every command's `--help`: allowed values shown, none of Typer's type labels."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import typer
from typer.testing import CliRunner

from trajcache.cli import app
from trajcache.cli.keys import KeyRole
from trajcache.cli.transfer import EvictionPolicy
from trajcache.services.catalog.keys import Role
from trajcache.services.maintenance.eviction import POLICIES

NOISE = ("<bool>", "<str>", "<int", "<float", "<path>", "<list", "{file}", "{")
DATABASE_COMMANDS = {
    ("serve",),
    ("migrate",),
    ("keys", "create"),
    ("keys", "list"),
    ("keys", "revoke"),
    ("export",),
    ("import",),
    ("prune",),
}


def _commands(command: object, words: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    yield words
    for name, sub in sorted(getattr(command, "commands", {}).items()):
        yield from _commands(sub, (*words, name))


COMMANDS = sorted(_commands(typer.main.get_command(app)))


def _help(words: tuple[str, ...]) -> str:
    result = CliRunner().invoke(app, [*words, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    return result.output


def test_every_command_group_is_listed() -> None:
    listed = {words[0] for words in COMMANDS if words}
    assert {"serve", "migrate", "worker", "keys", "seed", "export", "import", "prune"} <= listed
    assert {"reference", "openapi", "config-table", "demo", "warm", "robots"} <= listed


@pytest.mark.parametrize("words", COMMANDS, ids=lambda w: " ".join(w) or "trajcache")
def test_help_shows_no_type_labels(words: tuple[str, ...]) -> None:
    text = _help(words)
    assert not [n for n in NOISE if n in text], text
    assert "Usage:" in text


@pytest.mark.parametrize("words", sorted(DATABASE_COMMANDS), ids=" ".join)
def test_database_commands_take_a_database_url(words: tuple[str, ...]) -> None:
    assert "--database-url" in _help(words)


def test_help_lists_roles_and_policies() -> None:
    assert "[robot|seeder|admin]" in _help(("keys", "create"))
    assert f"[{'|'.join(POLICIES)}]" in _help(("prune",))
    assert [r.value for r in KeyRole] == [r.value for r in Role] == ["robot", "seeder", "admin"]
    assert tuple(p.value for p in EvictionPolicy) == POLICIES


def test_help_shows_a_required_argument_by_name() -> None:
    assert "import [OPTIONS] FILE" in _help(("import",))
