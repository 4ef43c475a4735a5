"""Data and workers of `bench/transfer.py`: an MBM-sized export, an import process, hits.

The export is written as a version-2 file (header, one model line, the trajectories, the end
line) without a database, so the import measured is the first thing that touches one. Its
trajectories are like MotionBenchMaker's Panda paths: 7 revolute joints, 4-8 key states each,
within joint limits, every one different (a random walk per trajectory).
"""

from __future__ import annotations

import json
import time
from datetime import UTC, datetime
from multiprocessing.queues import Queue
from pathlib import Path
from typing import Any

import numpy as np

from harness.report import pct
from trajcache.core.config import Settings
from trajcache.db.models import trajectory_content_hash
from trajcache_client import NO_RETRY, Client

ARM_JOINTS = 7
HIT_ROBOT = "transfer-hit-robot"
HIT_PATH = [[0.0, 0.0], [0.4, 0.3], [0.8, 0.5]]


def chain_urdf(name: str, joints: int) -> str:
    """A serial arm of `joints` revolute joints (limits ±2.8 rad) with a box per link."""
    links = ['<link name="l0"><collision><geometry><box size="0.1 0.1 0.1"/></geometry>'
             "</collision></link>"]  # fmt: skip
    chain = []
    for k in range(1, joints + 1):
        links.append(
            f'<link name="l{k}"><collision><origin xyz="0 0 0.05"/><geometry>'
            f'<box size="0.05 0.05 0.1"/></geometry></collision></link>'
        )
        axis = "0 0 1" if k % 2 else "0 1 0"
        chain.append(
            f'<joint name="j{k}" type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/>'
            f'<origin xyz="0 0 0.1"/><axis xyz="{axis}"/>'
            '<limit lower="-2.8" upper="2.8" effort="10" velocity="2"/></joint>'
        )
    return f'<?xml version="1.0"?><robot name="{name}">{"".join(links + chain)}</robot>'


def write_export(path: Path, rows: int, seed: int = 7) -> None:
    """An export of `rows` 7-joint trajectories of one model (its id: placeholder, resolved
    by the import from the model line)."""
    rng = np.random.default_rng(seed)
    now = datetime.now(UTC).isoformat()
    file_model = "mbm-like-arm"
    with path.open("w", encoding="utf-8") as out:
        header = {"type": "header", "format": "trajcache-export", "version": 2,
                  "exported_at": now, "filters": {}}  # fmt: skip
        out.write(json.dumps(header) + "\n")
        model = {"type": "model", "model_id": file_model, "name": "arm7", "base": "fixed",
                 "urdf": chain_urdf("arm7", ARM_JOINTS), "files": []}  # fmt: skip
        out.write(json.dumps(model) + "\n")
        for _ in range(rows):
            n = int(rng.integers(4, 9))
            start = rng.uniform(-2.0, 2.0, ARM_JOINTS)
            steps = rng.uniform(-0.3, 0.3, (n - 1, ARM_JOINTS))
            states = np.clip(np.vstack([start, start + np.cumsum(steps, axis=0)]), -2.7, 2.7)
            record = {"type": "trajectory", "model_id": file_model,
                      "states": states.round(6).tolist(), "source": "sim", "robot_id": None,
                      "scene_hash": None, "env": {}, "planning_time_ms": 40.0,
                      "created_at": now, "hits": 0, "failures": 0}  # fmt: skip
            record["content_hash"] = trajectory_content_hash(np.asarray(record["states"]))
            out.write(json.dumps(record, separators=(",", ":")) + "\n")
        out.write(json.dumps({"type": "end", "trajectories": rows}) + "\n")


def import_file(database_url: str, path: Path, queue: Queue[Any]) -> None:
    """Import `path` (run in a process of its own, as `trajcache import` runs); put
    (inserted, seconds of the import itself) on `queue`."""
    from trajcache.cli.transfer import IMPORT_NICENESS, lower_database_priority, lower_priority
    from trajcache.db import migrate
    from trajcache.db.session import make_engine, make_sessionmaker
    from trajcache.services.catalog.models import ModelRegistry
    from trajcache.services.maintenance.importer import import_lines
    from trajcache.services.maintenance.reading import CHUNK_BYTES, export_lines

    lower_priority(IMPORT_NICENESS)  # as `trajcache import` does
    settings = Settings(database_url=database_url)
    migrate.upgrade(settings.database_url)
    engine = make_engine(settings.database_url)
    queue.put("ready")
    with path.open("rb") as raw, make_sessionmaker(engine)() as session:
        lower_database_priority(session, IMPORT_NICENESS)  # as `trajcache import` does
        lines = export_lines(chunks=iter(lambda: raw.read(CHUNK_BYTES), b""), what="file")
        started = time.perf_counter()
        report = import_lines(
            session=session, registry=ModelRegistry(), settings=settings, lines=lines
        )
        queue.put((report.inserted, time.perf_counter() - started))
    engine.dispose()


def hit_setup(base: str) -> Client:
    """A client of the service at `base` whose robot (a 2-joint arm) has one cached path."""
    client = Client(base, timeout=60, retry=NO_RETRY)
    model = client.register_model(chain_urdf("hit2", 2), name="hit2")
    client.put_robot(HIT_ROBOT, model.model_id)
    client.store_trajectory(model.model_id, HIT_PATH, source="sim")
    for _ in range(20):  # warm: code paths, the index and the validator
        assert client.plan(HIT_ROBOT, HIT_PATH[0], HIT_PATH[-1], {"fallback": False}).ok
    return client


def one_hit(client: Client) -> float:
    """One cache hit of the robot; its latency (ms)."""
    started = time.perf_counter()
    answer = client.plan(HIT_ROBOT, HIT_PATH[0], HIT_PATH[-1], {"fallback": False})
    elapsed = (time.perf_counter() - started) * 1e3
    if not answer.ok:
        raise RuntimeError(f"expected a hit, got {answer.status}")
    return elapsed


def p99(samples: list[float]) -> float:
    """The 99th percentile (ms)."""
    return pct(samples, 99)
