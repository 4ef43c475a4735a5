"""`trajcache export`, `import` and `prune` on real databases (SQLite → SQLite or PostgreSQL)."""

from __future__ import annotations

import gzip
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
import sqlalchemy as sa
import typer
from click.testing import Result
from typer.testing import CliRunner

from tests.robots import TWO_JOINT_URDF
from trajcache.cli import app
from trajcache.cli.transfer import lower_database_priority, parse_duration
from trajcache.core.config import Settings
from trajcache.db import migrate
from trajcache.db.models import Trajectory, TrajectoryTombstone, utcnow
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.services.catalog.models import ModelRegistration, register_model
from trajcache.services.catalog.trajectories import NewTrajectory, store_trajectory
from trajcache.services.context import ServiceContext


@pytest.fixture
def source_url(tmp_path: Path) -> Iterator[str]:
    """A SQLite cache with five arm trajectories (two sim, three real; one a month old)."""
    url = f"sqlite:///{tmp_path / 'source.db'}"
    migrate.upgrade(url)
    ctx = ServiceContext.create(Settings(database_url=url, worker_backend="none"))
    with ctx.sessions() as session:
        model, _ = register_model(
            session=session,
            registry=ctx.models,
            registration=ModelRegistration(urdf=TWO_JOINT_URDF),
        )
        for k in range(5):
            new_id, _ = store_trajectory(
                session=session,
                settings=Settings(),
                trajectory=NewTrajectory(
                    model=model,
                    states=[[0.0, 0.0], [0.1 * k, 0.5]],
                    source="sim" if k < 2 else "real",
                ),
            )
            if k == 0:
                session.execute(
                    sa.update(Trajectory)
                    .where(Trajectory.id == new_id)
                    .values(created_at=utcnow() - timedelta(days=30))
                )
        session.commit()
    ctx.close()
    yield url


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def target_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'target.db'}"
    return str(request.getfixturevalue("postgres_url"))


def count(url: str, table: type = Trajectory) -> int:
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            return int(conn.execute(sa.select(sa.func.count()).select_from(table)).scalar_one())
    finally:
        engine.dispose()


def run(*args: str) -> Result:
    return CliRunner().invoke(app, list(args))


def test_export_gzip_then_import_twice(source_url: str, target_url: str, tmp_path: Path) -> None:
    out = tmp_path / "cache.jsonl.gz"
    result = run("export", "-o", str(out), "--database-url", source_url)
    assert result.exit_code == 0, result.output
    assert "exported 5 trajectories" in result.output
    lines = gzip.decompress(out.read_bytes()).decode().splitlines()
    assert [json.loads(line)["type"] for line in lines][:2] == ["header", "model"]

    result = run("import", str(out), "--database-url", target_url)
    assert result.exit_code == 0, result.output
    assert "trajectories imported" in result.output and "5" in result.output
    assert count(target_url) == 5
    again = run("import", str(out), "--database-url", target_url)
    assert again.exit_code == 0 and count(target_url) == 5
    assert "already there (skipped)" in again.output


def test_export_filters_and_stdout(source_url: str) -> None:
    def exported(*options: str) -> list[dict]:
        result = run("export", "--database-url", source_url, *options)
        assert result.exit_code == 0, result.output
        records = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
        return [r for r in records if r["type"] == "trajectory"]

    assert len(exported()) == 5
    assert {r["source"] for r in exported("--source", "sim")} == {"sim"}
    assert len(exported("--source", "sim", "--source", "real")) == 5
    assert len(exported("--newer-than", "7d")) == 4
    assert len(exported("--older-than", "1w")) == 1
    assert len(exported("--source", "sim", "--older-than", "2w")) == 1
    no_models = run("export", "--database-url", source_url, "--no-models").stdout
    assert '"type":"model"' not in no_models
    bad = run("export", "--database-url", source_url, "--model", "nope")
    assert bad.exit_code == 2 and "not found" in bad.output
    bad = run("export", "--database-url", source_url, "--newer-than", "soon")
    assert bad.exit_code == 2 and "not a duration" in bad.output


def test_corrupt_truncated_or_empty_files_import_nothing(source_url: str, tmp_path: Path) -> None:
    plain = tmp_path / "cache.jsonl"
    assert run("export", "-o", str(plain), "--database-url", source_url).exit_code == 0
    text = plain.read_bytes()
    packed = gzip.compress(text)
    target = f"sqlite:///{tmp_path / 'target.db'}"
    written = text[: text.rindex(b'{"type":"end"')]  # without the end line
    cases = {
        "cut.jsonl": (written + b'{"type": "trajectory", ', "line 8: not JSON"),
        "no-end.jsonl": (written, "ends without its end line: it was cut short"),
        "cut.jsonl.gz": (packed[:-4], f"gzip stream truncated after {len(packed) - 4} bytes"),
        "empty.jsonl": (b"\n", "empty file: nothing to import"),
    }
    for name, (data, needle) in cases.items():
        (tmp_path / name).write_bytes(data)
        result = run("import", str(tmp_path / name), "--database-url", target)
        assert result.exit_code == 2 and needle in result.output, (name, result.output)
        assert count(target) == 0
    (tmp_path / "whole.jsonl.gz").write_bytes(packed)
    assert run("import", str(tmp_path / "whole.jsonl.gz"), "--database-url", target).exit_code == 0
    assert count(target) == 5


def test_import_reports_rejected_lines_and_exits_1(source_url: str, tmp_path: Path) -> None:
    plain = tmp_path / "cache.jsonl"
    assert run("export", "-o", str(plain), "--database-url", source_url).exit_code == 0
    lines = plain.read_text().splitlines()
    lines.insert(3, '{"type": "trajectory", "model_id": "x", "states": [[0, 0], [0, 0]]}')
    lines.insert(4, "[1, 2]")
    plain.write_text("\n".join(lines) + "\n")
    target = f"sqlite:///{tmp_path / 'target.db'}"
    result = run("import", str(plain), "--database-url", target, "--source", "import")
    assert result.exit_code == 1
    assert "line 4: model 'x' is not in this database" in result.output
    assert "line 5: a line must be a JSON object" in result.output
    assert count(target) == 5
    foreign = tmp_path / "foreign.jsonl"
    foreign.write_text('{"type": "header", "format": "other", "version": 1}\n')
    result = run("import", str(foreign), "--database-url", target)
    assert result.exit_code == 2 and "not a trajcache export" in result.output


def test_prune_lists_then_applies(source_url: str) -> None:
    dry = run("prune", "--cap", "2", "--database-url", source_url)
    assert dry.exit_code == 0, dry.output
    assert "would delete 3 trajectories (dry run" in dry.output
    assert count(source_url) == 5
    applied = run("prune", "--cap", "2", "--apply", "--database-url", source_url)
    assert applied.exit_code == 0 and "deleted 3 trajectories" in applied.output
    assert count(source_url) == 2 and count(source_url, TrajectoryTombstone) == 3
    assert run("prune", "--database-url", source_url).exit_code == 2  # no cap anywhere
    assert run("prune", "--cap", "2", "--policy", "x", "--database-url", source_url).exit_code == 2


def test_durations() -> None:
    assert parse_duration("90", "--x") == timedelta(seconds=90)
    assert parse_duration("15m", "--x") == timedelta(minutes=15)
    assert parse_duration("1.5h", "--x") == timedelta(minutes=90)
    assert parse_duration("2w", "--x") == timedelta(days=14)
    with pytest.raises(typer.BadParameter):
        parse_duration("-1d", "--x")


def test_an_import_lowers_its_own_cpu_priority_by_its_niceness() -> None:
    """`--nice` (or TRAJCACHE_IMPORT_NICENESS) is added to the importing process's niceness;
    run in a child process, since it cannot be undone."""
    code = (
        "import os; from trajcache.cli.transfer import lower_priority; "
        "before = os.nice(0); lower_priority(3); lower_priority(0); print(os.nice(0) - before)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "3"


@pytest.mark.postgres
def test_an_import_lowers_its_database_backends_priority_too(postgres_url: str) -> None:
    """On a PostgreSQL server of this machine, the import's backend (which does its COPY and
    index work) gets the niceness too, where this user may renice it (root here)."""
    engine = make_engine(postgres_url)
    try:
        with make_sessionmaker(engine)() as session:
            pid = int(session.execute(sa.text("SELECT pg_backend_pid()")).scalar_one())
            before = os.getpriority(os.PRIO_PROCESS, pid)
            lowered = lower_database_priority(session, 3)
            after = os.getpriority(os.PRIO_PROCESS, pid)
    finally:
        engine.dispose()  # the reniced backend ends with its connection
    assert lowered or os.geteuid() != 0
    assert after - before == (min(3, 19 - before) if lowered else 0)


@pytest.mark.parametrize(
    "url", ["sqlite:///:memory:", "postgresql+psycopg://u@db.example.invalid:5432/x"]
)
def test_no_other_process_is_reniced(url: str) -> None:
    """A SQLite file has no backend, and a remote server's backend pid would name some other
    process of this machine: neither is touched (the remote one is not even connected)."""
    engine = make_engine(url)
    try:
        with make_sessionmaker(engine)() as session:
            assert not lower_database_priority(session, 3)
    finally:
        engine.dispose()
