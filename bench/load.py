"""Load: N simulated robots against two service replicas on one PostgreSQL database.

Starts `--replicas` `trajcache serve` processes on a fresh schema of the PostgreSQL server
(`--database-url`) and drives them with the reference workload (REFERENCE.md): the reference
robot in the restroom.

- Warm cache: cleaning run S is played once through the service (its calls split over two
  warm-up robots, one per replica), so the planner fills the cache.
- Robots: robot k (`load-k`, spread round-robin over the replicas) replays cleaning run S+1+k:
  its own execution noise and door angles, so its scene is never one a trajectory was planned
  in and every hit is validated. Before each call it brings its scene up to date (PUT, then
  PATCH of what changed), as a robot controller does.
- Misses: about `--miss-share` of the calls are replaced by a novel request that no cached
  trajectory serves: an arm move of the run with start and goal each moved off by 0.22-0.4 rad
  on three random joints (beyond the lookup threshold of 0.2), within limits and collision-free
  in the scene in force, so the planner must solve it.
- Pace: each robot asks for its next plan when its slot comes (the robots together offer
  `--rate` plans per second; a robot executes one trajectory before it asks for the next).
  Latency is measured from the slot, so a server that falls behind shows it. `--rate 0` sends
  each robot's next request as soon as the previous one is answered (capacity).

The client is one asyncio process (uvloop when installed) with one keep-alive HTTP/1.1
connection per robot over plain streams and pre-encoded bodies: it shares the machine with the
replicas, so it spends as little CPU per request as it can.

Reported: plans per second, latency p50 and p99 (all plans, and hits and misses apart), errors
(a non-2xx answer, a transport error, a plan without a trajectory or a scene hash the service
did not confirm), the share of plans served from the cache, server and client CPU per plan.
Afterwards every trajectory a response said the planner stored (source "planner" with a
trajectory id) is looked up in the schema's `trajectories` table and read through the replica
that did not plan it; one missing from either is `lost`. The last line printed is one JSON
object with `plans_per_s`, `p50_ms`, `p99_ms`, `errors`, `lost`, `hit_share`, `robots` and
`replicas`.

    python bench/load.py [--smoke] [--robots 64] [--duration 30] [--rate 320] [--workers 1]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sqlalchemy as sa

from harness.caches import fresh_schema
from harness.replay import RobotClient, register_reference_model
from harness.service import running_service, server_cpu_seconds
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.validator import build_validator
from trajcache.reference.cleaning import CleaningRun, PlanCall, cleaning_run
from trajcache.reference.robot import reference_model
from trajcache_client import NO_RETRY, APIError, Client

POSTGRES_URL = os.environ.get(
    "TRAJCACHE_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
PLAN_OPTIONS = {"fallback": True}
MISS_OFFSET_RAD = (0.22, 0.4)  # how far a miss's endpoint joints move (threshold: 0.2)
MISS_JOINTS = 3
REQUEST_TIMEOUT_S = 30.0
CAPACITY_GUESS = 800.0  # plans/s, to size the scripts of robots that do not wait (--rate 0)


@dataclass(frozen=True)
class Step:
    """One request of a robot's script, encoded once before the load starts."""

    kind: str  # "scene", "hit" (a call of the run) or "miss" (a novel request)
    method: str
    path: str
    body: bytes
    scene_hash: str = ""  # a scene step: the hash the service must answer


@dataclass
class Robot:
    """A simulated robot: its id, the replica it talks to and its requests in order."""

    robot_id: str
    replica: int
    steps: list[Step]


@dataclass
class Outcome:
    """What one plan request returned."""

    kind: str
    latency_ms: float
    ok: bool
    source: str | None = None
    trajectory_id: int | None = None
    replica: int = 0
    timings: dict[str, float] = field(default_factory=dict)  # the answer's timings_ms


@dataclass
class Tally:
    """Everything the robots observed."""

    plans: list[Outcome] = field(default_factory=list)
    scene_updates: int = 0
    errors: list[str] = field(default_factory=list)


class Connection:
    """One keep-alive HTTP/1.1 connection sending pre-encoded JSON requests."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None

    async def connect(self) -> None:
        """Open the connection (if it is not open)."""
        if self._reader is None or self._writer is None:
            self._reader, self._writer = await asyncio.open_connection(self.host, self.port)

    async def request(self, method: str, path: str, body: bytes) -> tuple[int, bytes]:
        """Send one request; its status code and body."""
        await self.connect()
        assert self._reader is not None and self._writer is not None
        head = (
            f"{method} {path} HTTP/1.1\r\nHost: {self.host}\r\n"
            f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n"
        )
        try:
            self._writer.write(head.encode() + body)
            raw = await self._reader.readuntil(b"\r\n\r\n")
            status = int(raw[9:12])
            headers = raw.decode("latin-1").lower()
            marker = headers.find("content-length:")
            if marker < 0:
                raise ConnectionError(f"answer {status} without content-length")
            length = int(headers[marker + 15 : headers.find("\r\n", marker)])
            content = await self._reader.readexactly(length)
            if "connection: close" in headers:
                self.close()
            return status, content
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Drop the connection (the next request opens a new one)."""
        if self._writer is not None:
            self._writer.close()
        self._reader = self._writer = None


# --- the robots' scripts -------------------------------------------------------------------


def scene_step(robot_id: str, scene: Scene, shown: dict[str, Any] | None) -> Step:
    """The request that makes `scene` the robot's scene: PUT at first, then a PATCH."""
    payload = scene_to_payload(scene)
    path = f"/v1/robots/{robot_id}/scene"
    if shown is None:
        return Step("scene", "PUT", path, json.dumps(payload).encode(), scene.hash)
    before = {o["id"]: o for o in shown["objects"]}
    after = {o["id"]: o for o in payload["objects"]}
    env: dict[str, float | None] = {
        k: v for k, v in payload["env"].items() if shown["env"].get(k) != v
    }
    env.update({k: None for k in shown["env"] if k not in payload["env"]})
    patch = {
        "upsert": [o for oid, o in after.items() if before.get(oid) != o],
        "remove": [oid for oid in before if oid not in after],
        "env": env,
    }
    return Step("scene", "PATCH", path, json.dumps(patch).encode(), scene.hash)


class MissMaker:
    """Novel, collision-free plan requests near the workload's arm moves."""

    def __init__(self, model: RobotModel, seed: int) -> None:
        self.model = model
        self.rng = np.random.default_rng(seed)
        arm = slice(3, model.dof)
        self.lower = np.maximum(model.lower[arm], -np.pi)
        self.upper = np.minimum(model.upper[arm], np.pi)
        self._checkers: dict[str, Any] = {}
        self._settings = Settings()

    def _free(self, scene: Scene, state: np.ndarray) -> bool:
        checker = self._checkers.get(scene.hash)
        if checker is None:
            checker = build_validator(self.model, scene, self._settings).checker
            self._checkers[scene.hash] = checker
        return not checker.state_contacts(state)

    def _moved(self, state: np.ndarray) -> np.ndarray | None:
        moved = state.copy()
        joints = self.rng.choice(len(self.lower), MISS_JOINTS, replace=False)
        offsets = self.rng.uniform(*MISS_OFFSET_RAD, MISS_JOINTS)
        signs = self.rng.choice([-1.0, 1.0], MISS_JOINTS)
        moved[3 + joints] += signs * offsets
        arm = moved[3:]
        if np.any(arm < self.lower) or np.any(arm > self.upper):
            return None
        return moved

    def make(self, call: PlanCall, scene: Scene) -> tuple[np.ndarray, np.ndarray] | None:
        """Start and goal of a miss derived from `call`, or None if none was found."""
        for _ in range(30):
            start, goal = self._moved(call.start), self._moved(call.goal)
            if start is None or goal is None:
                continue
            if self._free(scene, start) and self._free(scene, goal):
                return start, goal
        return None


def plan_step(robot_id: str, kind: str, start: np.ndarray, goal: np.ndarray) -> Step:
    """A plan request."""
    body = {"start": start.tolist(), "goal": goal.tolist(), "options": PLAN_OPTIONS}
    return Step(kind, "POST", f"/v1/robots/{robot_id}/plan", json.dumps(body).encode())


def robot_script(
    robot_id: str, runs: list[CleaningRun], calls: int | None, misses: MissMaker, share: float
) -> list[Step]:
    """The requests of one robot replaying the first `calls` calls of each of `runs`."""
    steps: list[Step] = []
    shown: dict[str, Any] | None = None
    shown_hash = ""
    for run in runs:
        played = run.calls[:calls]
        arm_moves = [c.index for c in played if not c.base_moves]
        count = min(len(arm_moves), round(share * len(played)))
        chosen = set(misses.rng.choice(arm_moves, count, replace=False).tolist())
        for call in played:
            scene = run.scene_for(call)
            if scene.hash != shown_hash:
                steps.append(scene_step(robot_id, scene, shown))
                shown, shown_hash = scene_to_payload(scene), scene.hash
            miss = misses.make(call, scene) if call.index in chosen else None
            if miss is not None:
                steps.append(plan_step(robot_id, "miss", *miss))
            else:
                steps.append(plan_step(robot_id, "hit", call.start, call.goal))
    return steps


# --- the load ------------------------------------------------------------------------------


async def drive(
    robot: Robot, conn: Connection, tally: Tally, *, slot: float, until: float, interval: float
) -> None:
    """Play the robot's script until `until`: each plan at its slot (or at once, interval 0).

    Scene updates go out as soon as the previous plan is answered (the scene changes while the
    robot executes), so a plan's latency is the plan's alone.
    """
    steps = _cycle(robot.steps)
    loop = asyncio.get_running_loop()
    while True:
        step = next(steps)
        while step.kind == "scene":
            await _scene(robot, conn, step, tally)
            step = next(steps)
        if interval > 0 and (wait := slot - loop.time()) > 0:
            await asyncio.sleep(wait)
        sent = slot if interval > 0 else loop.time()
        if sent >= until:
            return
        tally.plans.append(await _plan(robot, conn, step, tally, sent, loop))
        slot += interval


def _cycle(steps: list[Step]) -> Iterator[Step]:
    """The script over and over (a repeated hit is validated again only if the memo lost it)."""
    while True:
        yield from steps


async def _scene(robot: Robot, conn: Connection, step: Step, tally: Tally) -> None:
    try:
        status, content = await asyncio.wait_for(
            conn.request(step.method, step.path, step.body), REQUEST_TIMEOUT_S
        )
    except (TimeoutError, OSError, asyncio.IncompleteReadError, ValueError) as exc:
        tally.errors.append(f"{robot.robot_id} scene: {type(exc).__name__}: {exc}")
        return
    tally.scene_updates += 1
    if status // 100 != 2:
        tally.errors.append(f"{robot.robot_id} scene: {status} {content[:300]!r}")
    elif json.loads(content).get("hash") != step.scene_hash:
        tally.errors.append(f"{robot.robot_id} scene: hash differs from {step.scene_hash}")


async def _plan(
    robot: Robot,
    conn: Connection,
    step: Step,
    tally: Tally,
    sent: float,
    loop: asyncio.AbstractEventLoop,
) -> Outcome:
    try:
        status, content = await asyncio.wait_for(
            conn.request(step.method, step.path, step.body), REQUEST_TIMEOUT_S
        )
    except (TimeoutError, OSError, asyncio.IncompleteReadError, ValueError) as exc:
        tally.errors.append(f"{robot.robot_id} plan: {type(exc).__name__}: {exc}")
        return Outcome(step.kind, (loop.time() - sent) * 1e3, False, replica=robot.replica)
    latency = (loop.time() - sent) * 1e3
    if status != 200:
        tally.errors.append(f"{robot.robot_id} plan: {status} {content[:300]!r}")
        return Outcome(step.kind, latency, False, replica=robot.replica)
    answer = json.loads(content)
    ok = answer["status"] == "success"
    if not ok:
        tally.errors.append(f"{robot.robot_id} plan: {answer['status']}: {answer['message']}")
    return Outcome(
        step.kind,
        latency,
        ok,
        answer.get("source"),
        answer.get("trajectory_id"),
        robot.replica,
        answer.get("timings_ms") or {},
    )


async def run_load(
    robots: list[Robot], bases: list[str], *, duration_s: float, rate: float
) -> tuple[Tally, float]:
    """Drive every robot for `duration_s`; what they saw and the elapsed time (s)."""
    tally = Tally()
    conns = [Connection(*_host_port(bases[r.replica])) for r in robots]
    await asyncio.gather(*(conn.connect() for conn in conns))  # before the clock starts
    loop = asyncio.get_running_loop()
    interval = len(robots) / rate if rate > 0 else 0.0
    began = loop.time()
    until = began + duration_s
    await asyncio.gather(
        *(
            drive(
                r, c, tally, slot=began + interval * k / len(robots), until=until, interval=interval
            )
            for k, (r, c) in enumerate(zip(robots, conns, strict=True))
        )
    )
    elapsed = loop.time() - began
    for conn in conns:
        conn.close()
    return tally, elapsed


def _host_port(base: str) -> tuple[str, int]:
    host, _, port = base.removeprefix("http://").partition(":")
    return host, int(port)


def _event_loop_policy() -> None:
    try:
        import uvloop
    except ImportError:  # plain asyncio
        return
    asyncio.set_event_loop_policy(uvloop.EventLoopPolicy())


# --- setup and the check afterwards --------------------------------------------------------


def warm_cache(bases: list[str], model_id: str, run: CleaningRun, calls: int | None) -> int:
    """Play the first `calls` calls of `run` with fallback planning; trajectories planned."""
    played = run.calls[:calls]
    halves = [played[: len(played) // 2], played[len(played) // 2 :]]
    planned = [0, 0]
    failures: list[str] = []

    def play(k: int) -> None:
        with Client(bases[k % len(bases)], timeout=120, retry=NO_RETRY) as client:
            robot = RobotClient(client, f"warm-{k}", model_id, "sim")
            try:
                for call in halves[k]:
                    planned[k] += robot.call(run, call, PLAN_OPTIONS).planned
            except Exception as exc:  # reported below
                failures.append(str(exc))

    threads = [threading.Thread(target=play, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failures:
        raise RuntimeError(f"warm-up failed: {failures[0][:400]}")
    return sum(planned)


def register_robots(base: str, model_id: str, count: int) -> None:
    """Create robots load-0 … load-(count-1)."""
    with Client(base, timeout=60, retry=NO_RETRY) as client:
        for k in range(count):
            client.put_robot(f"load-{k}", model_id, kind="sim")


def _served(client: Client, trajectory_id: int) -> bool:
    """Whether the service of `client` answers GET /v1/trajectories/{trajectory_id} with 200."""
    try:
        client.get_trajectory(trajectory_id)
    except APIError:
        return False
    return True


def lost_trajectories(url: str, bases: list[str], plans: list[Outcome]) -> tuple[int, int]:
    """(planned trajectories answered, how many of them are missing) in the database or
    through the other replica."""
    planned = {(o.trajectory_id, o.replica) for o in plans if o.source == "planner"}
    ids = sorted({tid for tid, _ in planned if tid is not None})
    missing = sum(1 for tid, _ in planned if tid is None)
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            stored = set(
                conn.execute(
                    sa.text("SELECT id FROM trajectories WHERE id = ANY(:ids)"), {"ids": ids}
                ).scalars()
            )
    finally:
        engine.dispose()
    missing += len(set(ids) - stored)
    clients = [Client(b, timeout=30, retry=NO_RETRY) for b in bases]
    try:
        for tid, replica in sorted(p for p in planned if p[0] is not None):
            other = clients[(replica + 1) % len(clients)]
            if tid is not None and tid in stored and not _served(other, tid):
                missing += 1
    finally:
        for client in clients:
            client.close()
    return len(ids), missing


def pct(values: list[float], q: float) -> float:
    """The q-th percentile (0-100); NaN when there are none."""
    return float(np.percentile(values, q)) if values else float("nan")


def main() -> None:
    """Run the load and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="a few seconds, few robots (CI)")
    parser.add_argument("--robots", type=int, default=None, help="default 64 (smoke: 8)")
    parser.add_argument("--duration", type=float, default=None, help="seconds (default 30)")
    parser.add_argument("--rate", type=float, default=None, help="plans/s offered, 0: at once")
    parser.add_argument("--replicas", type=int, default=2)
    parser.add_argument("--workers", type=int, default=1, help="uvicorn workers per replica")
    parser.add_argument("--miss-share", type=float, default=0.1)
    parser.add_argument("--database-url", default=POSTGRES_URL, help="a PostgreSQL server")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    robots_n = args.robots or (8 if args.smoke else 64)
    duration = args.duration or (4.0 if args.smoke else 30.0)
    rate = args.rate if args.rate is not None else (80.0 if args.smoke else 320.0)
    calls = 60 if args.smoke else None  # calls per run played

    _event_loop_policy()
    model = reference_model()
    misses = MissMaker(model, args.seed)
    per_run = len(cleaning_run(args.seed).calls[:calls])
    expected = (rate or CAPACITY_GUESS) * duration / robots_n  # plans per robot
    runs = int(expected * 1.5 // per_run) + 1  # the script repeats only if the guess is short
    robots = [
        Robot(
            f"load-{k}",
            k % args.replicas,
            robot_script(
                f"load-{k}",
                [cleaning_run(args.seed + 1 + k + j * robots_n) for j in range(runs)],
                calls,
                misses,
                args.miss_share,
            ),
        )
        for k in range(robots_n)
    ]
    with ExitStack() as stack:
        url = stack.enter_context(fresh_schema(args.database_url))
        assert url is not None
        env = {"TRAJCACHE_AUTH_MODE": "off"}
        bases = [
            stack.enter_context(running_service(url, workers=args.workers, env=env))
            for _ in range(args.replicas)
        ]
        with Client(bases[0], timeout=60, retry=NO_RETRY) as client:
            model_id = register_reference_model(client)
        warmed = warm_cache(bases, model_id, cleaning_run(args.seed), calls)
        register_robots(bases[0], model_id, robots_n)
        cpu = [server_cpu_seconds(b) for b in bases]
        client_cpu = time.process_time()
        tally, elapsed = asyncio.run(run_load(robots, bases, duration_s=duration, rate=rate))
        client_cpu = time.process_time() - client_cpu
        server_cpu = sum(server_cpu_seconds(b) - c for b, c in zip(bases, cpu, strict=True))
        planned, lost = lost_trajectories(url, bases, tally.plans)

    plans = tally.plans
    answered = [o for o in plans if o.ok]
    hits = [o.latency_ms for o in answered if o.source == "cache"]
    fresh = [o.latency_ms for o in answered if o.source == "planner"]
    every = [o.latency_ms for o in plans]
    n = max(len(plans), 1)

    def server_ms(source: str, key: str) -> float:
        values = [o.timings.get(key, 0.0) for o in answered if o.source == source]
        return round(statistics.median(values), 3) if values else float("nan")

    summary = {
        "plans_per_s": round(len(plans) / elapsed, 1),
        "p50_ms": round(pct(every, 50), 3),
        "p99_ms": round(pct(every, 99), 3),
        "errors": len(tally.errors),
        "lost": lost,
        "hit_share": round(len(hits) / n, 4),
        "robots": robots_n,
        "replicas": args.replicas,
        "plans": len(plans),
        "planned": planned,
        "hit_p50_ms": round(pct(hits, 50), 3),
        "hit_p99_ms": round(pct(hits, 99), 3),
        "miss_p50_ms": round(pct(fresh, 50), 3),
        "miss_p99_ms": round(pct(fresh, 99), 3),
        "hit_server_total_ms": server_ms("cache", "total"),
        "miss_server_total_ms": server_ms("planner", "total"),
        "miss_server_plan_ms": server_ms("planner", "plan"),
        "scene_updates": tally.scene_updates,
        "offered_rate": rate,
        "duration_s": round(elapsed, 2),
        "server_cpu_ms_per_plan": round(server_cpu / n * 1e3, 3),
        "client_cpu_ms_per_plan": round(client_cpu / n * 1e3, 3),
        "warm_trajectories": warmed,
        "workers": args.workers,
        "smoke": args.smoke,
    }
    rows: list[tuple[str, object]] = [
        ("robots / replicas", f"{robots_n} / {args.replicas}"),
        ("offered plans/s", "as fast as answered" if rate <= 0 else rate),
        ("trajectories planned in warm-up", warmed),
        ("plans", len(plans)),
        ("plans/s", summary["plans_per_s"]),
        ("p50 ms", summary["p50_ms"]),
        ("p99 ms", summary["p99_ms"]),
        ("hit share", summary["hit_share"]),
        ("hits p50 / p99 ms", f"{summary['hit_p50_ms']} / {summary['hit_p99_ms']}"),
        ("planned p50 / p99 ms", f"{summary['miss_p50_ms']} / {summary['miss_p99_ms']}"),
        (
            "server total p50 ms: hit / planned",
            f"{summary['hit_server_total_ms']} / {summary['miss_server_total_ms']}",
        ),
        ("  of which planner p50 ms", summary["miss_server_plan_ms"]),
        ("scene updates", tally.scene_updates),
        ("errors", len(tally.errors)),
        ("planned trajectories checked", planned),
        ("lost", lost),
        ("server CPU per plan ms", summary["server_cpu_ms_per_plan"]),
        ("client CPU per plan ms", summary["client_cpu_ms_per_plan"]),
    ]
    print(f"{'measure':<34}{'value':>22}")
    for label, value in rows:
        text = f"{value:.3f}" if isinstance(value, float) else str(value)
        print(f"{label:<34}{text:>22}")
    for error in tally.errors[:5]:
        print(f"error: {error[:300]}")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
