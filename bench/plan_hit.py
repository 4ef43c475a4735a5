"""End-to-end cache-hit latency of POST /v1/robots/{id}/plan through the real service.

Starts `trajcache serve` (uvicorn on loopback, SQLite by default), registers the reference robot,
uploads the restroom scene, stores collision-free trajectories, then asks for plans whose start
and goal are near stored ones (execution noise), so every answer is a validated cache hit.
Measures client latency sequentially and with 16 concurrent clients, and the server-side
breakdown (lookup, validation, database; serialization and HTTP = client latency − server total).

    python bench/plan_hit.py [--smoke] [--database-url postgresql+psycopg://…]
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time

import httpx
import numpy as np

from _service import running_service
from trajcache.geometry.collision import CollisionChecker
from trajcache.geometry.reference.restroom import restroom_scene
from trajcache.geometry.reference.robot import reference_model, reference_urdf
from trajcache.geometry.scene import scene_to_payload
from trajcache.geometry.validation import TrajectoryValidator
from validation import make_trajectories

CONCURRENCY = 16


def percentile(values: list[float], q: float) -> float:
    """The q-th percentile (0–100) of `values`."""
    return float(np.percentile(np.asarray(values), q))


def setup_cache(base: str, count: int, seed: int) -> list[tuple[list[float], list[float]]]:
    """Register the robot and scene, store `count` trajectories; return noisy (start, goal)s."""
    model = reference_model()
    scene = restroom_scene(doors=[30.0, 60.0, 90.0])
    rng = np.random.default_rng(seed)
    with httpx.Client(base_url=base, timeout=30) as client:
        reply = client.post(
            "/v1/robot-models",
            json={"urdf": reference_urdf(), "base": "planar", "name": "xarm7-mobile"},
        )
        reply.raise_for_status()
        model_id = reply.json()["model_id"]
        client.put("/v1/robots/bench-1", json={"model_id": model_id}).raise_for_status()
        client.put("/v1/robots/bench-1/scene", json=scene_to_payload(scene)).raise_for_status()
        validator = TrajectoryValidator(model, scene)
        free, _ = make_trajectories(model, CollisionChecker(model, scene), rng, count * 2)
        queries = []
        for key in free:
            key = key.copy()
            key[:, :3] = key[0, :3]  # the arm moves, the base stays: the common case
            if not validator.validate(key).valid:
                continue
            client.post(
                "/v1/trajectories",
                json={"model_id": model_id, "states": key.tolist(), "source": "sim"},
            ).raise_for_status()
            for _ in range(3):
                start, goal = key[0].copy(), key[-1].copy()
                start[3:] += rng.uniform(-0.01, 0.01, size=7)
                goal[3:] += rng.uniform(-0.01, 0.01, size=7)
                goal[:3] = start[:3]
                start = np.clip(start, model.lower, model.upper)
                goal = np.clip(goal, model.lower, model.upper)
                queries.append((start.tolist(), goal.tolist()))
            if len(queries) >= count * 3:
                break
    return queries


def run_sequential(
    base: str, queries: list[tuple[list[float], list[float]]], n: int
) -> tuple[list[float], list[dict[str, float]], int]:
    """Latencies (ms), server timings and hit count of `n` sequential plans."""
    latencies, timings, hits = [], [], 0
    with httpx.Client(base_url=base, timeout=30) as client:
        for i in range(n):
            start, goal = queries[i % len(queries)]
            began = time.perf_counter()
            reply = client.post(
                "/v1/robots/bench-1/plan",
                json={"start": start, "goal": goal, "options": {"fallback": False}},
            )
            latencies.append((time.perf_counter() - began) * 1e3)
            body = reply.json()
            hits += body.get("source") == "cache"
            timings.append(body.get("timings_ms", {}))
    return latencies, timings, hits


def run_concurrent(base: str, queries: list[tuple[list[float], list[float]]], n: int) -> float:
    """Plans per second with CONCURRENCY clients sending `n` requests in all."""
    per_client = n // CONCURRENCY
    errors: list[str] = []

    def worker(offset: int) -> None:
        with httpx.Client(base_url=base, timeout=30) as client:
            for i in range(per_client):
                start, goal = queries[(offset * 7 + i) % len(queries)]
                reply = client.post(
                    "/v1/robots/bench-1/plan",
                    json={"start": start, "goal": goal, "options": {"fallback": False}},
                )
                if reply.status_code != 200:
                    errors.append(reply.text)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(CONCURRENCY)]
    began = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - began
    if errors:
        print(f"{len(errors)} errors, first: {errors[0][:200]}")
    return per_client * CONCURRENCY / elapsed


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="tiny run for CI")
    parser.add_argument("--database-url", default=None, help="default: a temporary SQLite file")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    stored, sequential, concurrent = (10, 60, 160) if args.smoke else (100, 600, 3200)

    with running_service(args.database_url) as base:
        queries = setup_cache(base, stored, args.seed)
        run_sequential(base, queries, 30)  # warm-up: connections, caches, validators
        latencies, timings, hits = run_sequential(base, queries, sequential)
        rps = run_concurrent(base, queries, concurrent)

    def med(key: str) -> float:
        return statistics.median(t.get(key, 0.0) for t in timings)

    client_minus_server = statistics.median(
        lat - t.get("total", 0.0) for lat, t in zip(latencies, timings, strict=True)
    )
    p50, p99 = percentile(latencies, 50), percentile(latencies, 99)
    print(f"{'measure':<34}{'value':>10}")
    for label, value in (
        ("stored trajectories", len(queries) // 3),
        ("sequential requests", sequential),
        ("cache hits", hits),
        ("client p50 ms", p50),
        ("client p99 ms", p99),
        ("server lookup p50 ms", med("lookup")),
        ("server validate p50 ms", med("validate")),
        ("server db p50 ms", med("db")),
        ("server total p50 ms", med("total")),
        ("http + serialization p50 ms", client_minus_server),
        (f"concurrent rps ({CONCURRENCY} clients)", rps),
    ):
        print(
            f"{label:<34}{value:>10.3f}" if isinstance(value, float) else f"{label:<34}{value:>10}"
        )
    print(
        json.dumps(
            {
                "p50_ms": round(p50, 3),
                "p99_ms": round(p99, 3),
                "concurrent_rps": round(rps, 1),
                "hit_rate": round(hits / sequential, 4),
                "server_lookup_ms": round(med("lookup"), 3),
                "server_validate_ms": round(med("validate"), 3),
                "server_db_ms": round(med("db"), 3),
                "http_serialization_ms": round(client_minus_server, 3),
                "database": "postgresql" if args.database_url else "sqlite",
                "smoke": args.smoke,
            }
        )
    )


if __name__ == "__main__":
    main()
