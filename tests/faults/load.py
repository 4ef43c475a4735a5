"""Plan and write load against a live app, and the checks of what it left in the database.

`Load` drives three kinds of requests from threads, each with its own HTTP connection:
- `hit`: a plan whose start and goal are those of a seeded trajectory (a cache hit; its usage
  counters and plan event are written by the app's background recorder);
- `miss`: a plan between fresh random states (planned in the local pool, then stored);
- `write`: POST /v1/trajectories with fresh random states.
Every answer is kept, with when it was asked and answered, for the checks that follow.
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import httpx
import numpy as np
import sqlalchemy as sa

from tests.waiting import wait_until
from trajcache.db.models import PlanEvent, Trajectory, trajectory_content_hash, unpack_states
from trajcache.services.catalog.models import get_model
from trajcache.services.context import ServiceContext

ROBOT = "r1"
KINDS = ("hit", "miss", "write")
REQUEST_TIMEOUT_S = 30.0  # far above any bound checked: a hung request is seen, not aborted
# Joint ranges of random states: free of self-collision for the 2-joint arm, in an empty scene.
LOW, HIGH = np.array([-1.2, -0.8]), np.array([1.2, 0.8])


@dataclass
class Outcome:
    """One request and its answer."""

    kind: str
    began: float
    ended: float
    status: int  # 0: no HTTP answer (connection error or client timeout)
    body: Any
    states: list[list[float]]  # what was written, or the plan's start and goal

    @property
    def ok(self) -> bool:
        return 200 <= self.status < 300

    @property
    def took(self) -> float:
        return self.ended - self.began

    def describe(self) -> str:
        return f"{self.kind} {self.status} after {self.took:.2f} s: {self.body!r:.300}"


@dataclass
class Load:
    """Request threads against the app at `url`; `model_id` has robot `r1` in an empty scene."""

    url: str
    model_id: str
    seeded: list[list[list[float]]]  # states of the trajectories that hits reuse
    threads: dict[str, int] = field(default_factory=lambda: {"hit": 2, "miss": 1, "write": 1})
    pause_s: float = 0.02  # between two requests of a thread: leaves CPU to the app
    outcomes: list[Outcome] = field(default_factory=list)
    _stop: threading.Event = field(default_factory=threading.Event)
    _running: list[threading.Thread] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def start(self) -> None:
        for kind, count in self.threads.items():
            for seed in range(count):
                thread = threading.Thread(target=self._drive, args=(kind, seed), daemon=True)
                thread.start()
                self._running.append(thread)

    def stop(self) -> None:
        self._stop.set()
        for thread in self._running:
            thread.join(timeout=REQUEST_TIMEOUT_S + 5.0)
        assert not any(t.is_alive() for t in self._running), "a load thread hung"

    def of(self, kind: str | None = None) -> list[Outcome]:
        with self._lock:
            return [o for o in self.outcomes if kind is None or o.kind == kind]

    def wait_for_successes(self, since: float, count: int, timeout: float) -> bool:
        """Wait until every kind has `count` successes among the requests sent after `since`."""

        def reached() -> bool:
            done = Counter(o.kind for o in self.of() if o.ok and o.began > since)
            return all(done[kind] >= count for kind in self.threads)

        return wait_until(reached, timeout_s=timeout, interval_s=0.05)

    def _drive(self, kind: str, seed: int) -> None:
        rng = np.random.default_rng([KINDS.index(kind), seed, int(time.time())])
        with httpx.Client(base_url=self.url, timeout=REQUEST_TIMEOUT_S) as client:
            n = 0
            while not self._stop.is_set():
                self._record(kind, client, rng, n)
                n += 1
                self._stop.wait(self.pause_s)

    def _record(self, kind: str, client: httpx.Client, rng: np.random.Generator, n: int) -> None:
        if kind == "hit":
            states = self.seeded[n % len(self.seeded)]
            states = [states[0], states[-1]]
        else:
            states = rng.uniform(LOW, HIGH, size=(2 if kind == "miss" else 3, 2)).tolist()
        began = time.monotonic()
        try:
            if kind == "write":
                reply = client.post(
                    "/v1/trajectories",
                    json={"model_id": self.model_id, "states": states, "source": "sim"},
                )
            else:
                reply = client.post(
                    f"/v1/robots/{ROBOT}/plan", json={"start": states[0], "goal": states[-1]}
                )
            status, body = reply.status_code, _json(reply)
        except httpx.HTTPError as exc:
            status, body = 0, repr(exc)
        outcome = Outcome(kind, began, time.monotonic(), status, body, states)
        with self._lock:
            self.outcomes.append(outcome)


def _json(reply: httpx.Response) -> Any:
    try:
        return reply.json()
    except ValueError:
        return reply.text


def seed_trajectories(client: httpx.Client, model_id: str, count: int) -> list[list[list[float]]]:
    """Store `count` straight trajectories for hits to reuse; their states."""
    rng = np.random.default_rng(7)
    seeded = []
    for _ in range(count):
        states = rng.uniform(LOW, HIGH, size=(2, 2)).tolist()
        reply = client.post(
            "/v1/trajectories", json={"model_id": model_id, "states": states, "source": "sim"}
        )
        assert reply.status_code == 201, reply.text
        seeded.append(states)
    return seeded


# --- what the load left in the database ---


def check_database(engine: sa.Engine, load: Load, ctx: ServiceContext) -> dict[str, int]:
    """No half-written rows: the database holds exactly what the answers say; counts checked."""
    assert ctx.records.flush(timeout=30.0), "plan records were not written after the outage"
    assert ctx.records.stats().dropped == 0, ctx.records.stats()
    with engine.connect() as conn:
        rows = {r.id: r for r in conn.execute(sa.select(Trajectory.__table__))}
        events = list(conn.execute(sa.select(PlanEvent.__table__)))
    by_hash = {r.content_hash: r for r in rows.values()}
    for row in rows.values():  # every stored row is whole
        states = unpack_states(row.states, n_states=row.n_states, dof=row.dof)
        assert states.shape == (row.n_states, 2) and row.n_states >= 2, row.id
        assert trajectory_content_hash(states) == row.content_hash, row.id
        assert [row.start, row.goal] == [states[0].tolist(), states[-1].tolist()], row.id

    counts: Counter[str] = Counter()
    for o in load.of("write"):
        stored = by_hash.get(trajectory_content_hash(np.asarray(o.states)))
        if o.ok:  # answered as stored: it is, with these states, under the answered id
            assert stored is not None and stored.id == o.body["trajectory_id"], o.describe()
            counts["write_stored"] += 1
        elif stored is not None:  # committed, but the answer was lost with the connection
            counts["write_failed_but_committed"] += 1
        else:
            counts["write_failed"] += 1

    planned = [o for o in load.of("miss") if o.ok and o.body.get("source") == "planner"]
    for o in planned:  # a planned answer is stored as answered
        found = rows.get(o.body["trajectory_id"])
        assert found is not None, o.describe()
        states = unpack_states(found.states, n_states=found.n_states, dof=found.dof)
        assert np.allclose(states, o.body["states"]), o.describe()
    planner_events = Counter(e.trajectory_id for e in events if e.source == "planner")
    for o in planned:
        assert planner_events[o.body["trajectory_id"]] >= 1, o.describe()
    counts["miss_planned"] = len(planned)

    served = [o for o in load.of() if o.ok and o.kind != "write" and o.body["source"] == "cache"]
    cache_events = [e for e in events if e.source == "cache" and e.status == "success"]
    # Each answered hit has its plan event and its hit counted, exactly once.
    assert len(cache_events) == len(served), (len(cache_events), len(served))
    assert sum(r.hits for r in rows.values()) == len(served)
    assert all(e.trajectory_id in rows for e in events if e.trajectory_id is not None)
    counts["hits_served"] = len(served)

    check_index(ctx, load.model_id, set(rows))
    return dict(counts)


def check_index(ctx: ServiceContext, model_id: str, stored_ids: set[int]) -> None:
    """The app's in-memory index and states cache agree with the database."""
    with ctx.sessions() as session:
        model = get_model(session=session, registry=ctx.models, model_id=model_id)
        indexed = set(ctx.indexes.index(session, model).ids().tolist())
        cached = ctx.indexes.states(session, sorted(stored_ids))
        with_states = {
            r.id: unpack_states(r.states, n_states=r.n_states, dof=r.dof)
            for r in session.execute(
                sa.select(Trajectory.id, Trajectory.states, Trajectory.n_states, Trajectory.dof)
            )
        }
    assert indexed == stored_ids, (sorted(indexed - stored_ids), sorted(stored_ids - indexed))
    for trajectory_id, states in cached.items():
        assert np.array_equal(states, with_states[trajectory_id]), trajectory_id
