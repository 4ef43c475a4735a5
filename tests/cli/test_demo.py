"""`trajcache demo`: the short protocol on its own services, end to end."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from trajcache.cli import app


@pytest.mark.parametrize(
    ("doors", "needle"), [("0,x", "must be integers"), ("0,120", "0…90°"), (",", "0…90°")]
)
def test_bad_door_angles_are_a_usage_error(doors: str, needle: str) -> None:
    result = CliRunner().invoke(app, ["demo", "--doors", doors])
    assert result.exit_code == 2
    assert needle in result.output


@pytest.mark.slow
def test_demo_prints_both_tables_and_finds_no_collision(tmp_path: object) -> None:
    cmd = [sys.executable, "-m", "trajcache.cli", "demo", "--calls", "6", "--doors", "0,90",
           "--no-arm", "--json", f"{tmp_path}/demo.json"]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=280, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    # A line for each of the 4 services (caches none, sim, seeded, real) as it becomes ready,
    # and the services stop without warnings.
    assert done.stderr.count("cache ready at http://127.0.0.1:") == 4, done.stderr[-3000:]
    assert "leaked" not in done.stderr and "resource_tracker" not in done.stderr, done.stderr
    lines = done.stdout.strip().splitlines()
    assert any(line.startswith("Table 1: simulation (6 calls per run") for line in lines)
    assert any(line.startswith("Table 2: pre-seeding and the real robot") for line in lines)
    assert not any(line.startswith("+ ") for line in lines)  # --no-arm
    summary = json.loads(lines[-1])
    assert summary["collisions"] == 0 and summary["failed_calls"] == 0
    assert summary["trajectories_checked"] == 9 * 6  # 9 rows of 6 calls, every one checked
    assert 0.0 < summary["run2_hit_rate"] <= 1.0
    assert summary["real_seeded_hit_rate"] is not None
    document = json.loads((tmp_path / "demo.json").read_text())  # type: ignore[operator]
    assert len(document["rows"]) == 9
