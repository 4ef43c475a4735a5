"""bench/load.py's client: one asyncio process driving every robot over keep-alive connections.

Each robot has one HTTP/1.1 connection to its replica and sends pre-encoded bodies over plain
streams, so the client spends as little CPU per request as it can. A robot asks for its next
plan when its slot comes; latency is measured from the slot, so a server that falls behind
shows it.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from dataclasses import dataclass, field

from load_scripts import Step

REQUEST_TIMEOUT_S = 30.0


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


def install_event_loop_policy() -> None:
    """Run asyncio on uvloop when it is installed."""
    try:
        import uvloop
    except ImportError:  # plain asyncio
        return
    asyncio.set_event_loop_policy(uvloop.EventLoopPolicy())
