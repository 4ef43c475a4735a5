"""Bulk transfer at fleet scale: import and export of MBM-sized trajectories, and hits meanwhile.

A fleet pre-seeds its cache from simulation in bulk. This benchmark writes an export of
`--rows` trajectories like MotionBenchMaker's Panda paths (7 joints, 4-8 key states), then on
SQLite and on PostgreSQL (a schema of its own, dropped afterwards):

1. imports it in a process of its own, as `trajcache import` does (one transaction, batched
   inserts, quality left to the service's background pass), and times the import itself;
2. on PostgreSQL, meanwhile, a running service answers cache hits of another robot: their p99
   while the import runs is set against their p99 before it (an import must not stall the
   service);
3. exports every trajectory again (streamed) and times it.

    python bench/transfer.py            # 100,000 trajectories
    python bench/transfer.py --smoke    # 2,000 (CI)

Targets (issue 31): import >= 5,000 trajectories/s and export >= 20,000/s on PostgreSQL; hits
during an import within 2x their idle p99. The last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import queue
import tempfile
import time
from pathlib import Path
from typing import Any

from harness.caches import fresh_schema
from harness.report import print_measures
from harness.service import running_service
from harness.transfer_data import hit_setup, import_file, one_hit, p99, write_export
from trajcache.db.session import make_engine, make_sessionmaker
from trajcache.services.maintenance.transfer import ExportFilter, dumps, export_records

POSTGRES = os.environ.get("TRAJCACHE_BENCH_POSTGRES", "postgresql://postgres@127.0.0.1:5432/test")
SERVICE_ENV = {"TRAJCACHE_WORKER_BACKEND": "none"}  # hits only: no planner processes
IMPORT_DEADLINE_S = 1800.0


def start_import(url: str, path: Path) -> tuple[Any, Any]:
    """The import process (started) and its queue, once it is ready to import."""
    ctx = multiprocessing.get_context("fork")  # the parent has imported trajcache already
    results = ctx.Queue()
    proc = ctx.Process(target=import_file, args=(url, path, results), daemon=True)
    proc.start()
    if results.get(timeout=300) != "ready":
        raise RuntimeError("the import process did not start")
    return proc, results


def finish_import(
    proc: Any, results: Any, timeout_s: float = IMPORT_DEADLINE_S
) -> tuple[int, float]:
    """(inserted, seconds) of the import process."""
    inserted, seconds = results.get(timeout=timeout_s)
    proc.join(60)
    return int(inserted), float(seconds)


def timed_export(url: str, out: Path) -> tuple[int, float]:
    """(trajectories exported, seconds) of a full export of `url` to `out`."""
    engine = make_engine(url)
    written = 0
    started = time.perf_counter()
    with make_sessionmaker(engine)() as session, out.open("w", encoding="utf-8") as handle:
        for record in export_records(session=session, filt=ExportFilter()):
            handle.write(dumps(record) + "\n")
            written += record["type"] == "trajectory"
    seconds = time.perf_counter() - started
    engine.dispose()
    return written, seconds


def sqlite_round(path: Path, tmp: Path, rows: int) -> dict[str, float]:
    """Import and export on a fresh SQLite file."""
    url = f"sqlite:///{tmp / 'bench.db'}"
    inserted, import_s = finish_import(*start_import(url, path))
    exported, export_s = timed_export(url, tmp / "sqlite-export.jsonl")
    assert inserted == rows and exported == rows, (inserted, exported)
    return {"import_per_s_sqlite": rows / import_s, "export_per_s_sqlite": rows / export_s}


def hits_while_importing(base: str, url: str, path: Path, idle_hits: int) -> dict[str, Any]:
    """Hit p99 idle, then while the import runs (until it ends); the import's figures."""
    with hit_setup(base) as client:
        idle = [one_hit(client) for _ in range(idle_hits)]
        proc, results = start_import(url, path)
        during: list[float] = []
        outcome = None
        while outcome is None:
            during.append(one_hit(client))
            try:
                outcome = results.get_nowait()
            except queue.Empty:
                continue
        proc.join(60)
    inserted, seconds = outcome
    return {
        "inserted": int(inserted),
        "import_s": float(seconds),
        "hit_p99_ms_idle": p99(idle),
        "hit_p99_ms_during_import": p99(during),
        "hits_during_import": len(during),
    }


def postgres_round(path: Path, tmp: Path, rows: int, idle_hits: int) -> dict[str, Any]:
    """Import (with a service answering hits meanwhile) and export on a fresh schema."""
    with fresh_schema(POSTGRES) as url:
        assert url is not None
        with running_service(url, env=SERVICE_ENV, deadline_s=300) as base:
            measured = hits_while_importing(base, url, path, idle_hits)
        exported, export_s = timed_export(url, tmp / "pg-export.jsonl")
    # the export holds the hit robot's trajectory too
    assert measured["inserted"] == rows and exported == rows + 1, (measured["inserted"], exported)
    return {
        "import_per_s": rows / measured.pop("import_s"),
        "export_per_s": rows / export_s,
        **{k: v for k, v in measured.items() if k != "inserted"},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--smoke", action="store_true", help="2,000 rows (CI)")
    parser.add_argument("--rows", type=int, default=None, help="trajectories (default 100,000)")
    args = parser.parse_args()
    rows = args.rows or (2_000 if args.smoke else 100_000)
    idle_hits = 200 if args.smoke else 1000
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        path = tmp / "export.jsonl"
        write_export(path, rows)
        result: dict[str, Any] = {"rows": rows, "smoke": args.smoke}
        result.update(sqlite_round(path, tmp, rows))
        result.update(postgres_round(path, tmp, rows, idle_hits))
    targets = {
        "import_per_s >= 5000": result["import_per_s"] >= 5000,
        "export_per_s >= 20000": result["export_per_s"] >= 20000,
        "hit p99 during import <= 2x idle": result["hit_p99_ms_during_import"]
        <= 2 * result["hit_p99_ms_idle"],
    }
    print(f"bulk transfer of {rows} trajectories (7 joints, 4-8 states)")
    print_measures([(k, v) for k, v in result.items() if k != "smoke"], 30, 14)
    for name, met in targets.items():
        print(f"target {name}: {'met' if met else 'NOT met'}")
    print(json.dumps({**result, "targets_met": all(targets.values())}))


if __name__ == "__main__":
    main()
