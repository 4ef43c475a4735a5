"""bench/paper_tables.py end to end on a few calls: real services, tables, JSON, chart."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.replay import CallRecord
from harness.tables import Row, format_table, speedups

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "paper_tables.py"
ROWS = "sim_none,run1,run2,run1_arm,real_none"  # three services, both tables


def _record(source: str, total: float, tried: int = 1) -> CallRecord:
    timings = {"lookup": 1.0, "validate": 4.0, "plan": total - 10 if source == "planner" else 0.0}
    timings |= {"db": 5.0, "total": total}
    return CallRecord(
        index=0, label="stall 1: a → b", base_moves=False, start=np.zeros(10), goal=np.zeros(10),
        scene_hash="h", status="success", source=source, trajectory_id=1,
        candidates_tried=tried, timings=timings, wall_ms=total + 2, states=None,
    )  # fmt: skip


def test_rows_sum_the_service_timings_and_divide_by_the_no_cache_row() -> None:
    none = Row("sim_none", 1, "no cache", "sim_none", [_record("planner", 100.0)] * 4, None)
    run = Row("run2", 1, "run 2", "sim_none", [_record("cache", 10.0)] * 3, 3)
    run.records.append(_record("planner", 100.0, tried=0))
    rows = {"sim_none": none, "run2": run}
    figures = run.figures()
    assert (figures["calls"], figures["hits"], figures["planner_calls"]) == (4, 3, 1)
    assert figures["total_s"] == pytest.approx(0.13)
    assert figures["lookup_validate_s"] == pytest.approx(0.02)
    assert speedups(run, rows)["speedup"] == pytest.approx(0.4 / 0.13)
    assert run.misses()["causes"] == {"no cached start/goal within the threshold": 1}
    table = format_table("Table 1", 1, rows)
    assert "    paper" in table and "3.31×" in table  # the paper's run 2 under ours


@pytest.mark.slow
def test_smoke_runs_end_to_end(tmp_path: Path) -> None:
    out_json, chart = tmp_path / "tables.json", tmp_path / "tables.png"
    cmd = [sys.executable, str(SCRIPT), "--smoke", "--calls", "8", "--rows", ROWS,
           "--json", str(out_json), "--chart", str(chart)]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=280, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.strip().splitlines()
    summary = json.loads(lines[-1])
    assert summary["collisions"] == 0 and summary["endpoint_errors"] == 0
    assert summary["failed_calls"] == 0
    assert 0.0 < summary["run2_hit_rate"] <= 1.0 and summary["run2_speedup"] > 0
    assert summary["real_seeded_hit_rate"] is None  # not among the rows played
    assert any(line.startswith("Table 1") for line in lines)
    assert any(line.startswith("Table 2") for line in lines)
    document = json.loads(out_json.read_text())
    assert [row["key"] for row in document["rows"]] == ROWS.split(",")
    assert all(row["calls"] == 8 and row["collisions"] == 0 for row in document["rows"])
    assert chart.stat().st_size > 10_000
