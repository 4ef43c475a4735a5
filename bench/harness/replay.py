"""A robot that plays cleaning runs through the REST API, as a robot controller would.

Before each call it brings the service's copy of its scene up to date: the first scene is sent
whole (PUT), every later change (a door opened, a seat raised) as a PATCH of the objects and
environment values that changed. The hash the service answers must equal the scene's own hash,
so the service always plans in exactly the scene in force at that call.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.cleaning import CleaningRun, PlanCall
from trajcache.reference.robot import REFERENCE_BASE, REFERENCE_NAME, reference_urdf
from trajcache_client import APIError, Client, PlanResult

TIMING_KEYS = ("lookup", "validate", "plan", "db", "total")  # always present in a record


@dataclass
class CallRecord:
    """One planning call of a run and what the service answered."""

    index: int
    label: str
    base_moves: bool
    start: FloatArray
    goal: FloatArray
    scene_hash: str
    status: str
    source: str | None
    trajectory_id: int | None
    candidates_tried: int
    timings: dict[str, float]
    wall_ms: float
    states: FloatArray | None
    rejected: list[dict[str, Any]] = field(default_factory=list)
    message: str = ""

    @property
    def hit(self) -> bool:
        """Whether the answer came from the cache."""
        return self.status == "success" and self.source == "cache"

    @property
    def planned(self) -> bool:
        """Whether the fallback planner was called and found a path."""
        return self.status == "success" and self.source == "planner"

    def summary(self) -> dict[str, Any]:
        """The call as JSON, without its states."""
        return {
            "index": self.index,
            "label": self.label,
            "status": self.status,
            "source": self.source,
            "trajectory_id": self.trajectory_id,
            "candidates_tried": self.candidates_tried,
            "rejected": [f"{r['status']}: {r['reason']}" for r in self.rejected],
            "key_states": None if self.states is None else len(self.states),
            "timings_ms": self.timings,
            "wall_ms": round(self.wall_ms, 3),
        }


def register_reference_model(client: Client) -> str:
    """Register the reference robot's model; its id."""
    model = client.register_model(reference_urdf(), base=REFERENCE_BASE, name=REFERENCE_NAME)
    return model.model_id


def cached_count(client: Client, model_id: str) -> int:
    """How many trajectories of `model_id` the cache holds."""
    return client.list_trajectories(model_id=model_id, limit=1).total


class RobotClient:
    """One robot of the service: keeps its scene current and asks for plans."""

    def __init__(self, client: Client, robot_id: str, model_id: str, kind: str) -> None:
        self.client, self.robot_id = client, robot_id
        client.put_robot(robot_id, model_id, kind=cast(Any, kind))
        self._objects: dict[str, dict[str, Any]] | None = None
        self._env: dict[str, float] = {}
        self.scene_hash = ""
        self.scene_updates = 0

    def show(self, scene: Scene) -> None:
        """Make `scene` the robot's scene at the service (PUT at first, then PATCH changes)."""
        if scene.hash == self.scene_hash:
            return
        payload = scene_to_payload(scene)
        objects = {o["id"]: o for o in payload["objects"]}
        if self._objects is None:
            reply = self.client.put_scene(self.robot_id, payload)
        else:
            env: dict[str, float | None] = {
                k: v for k, v in payload["env"].items() if self._env.get(k) != v
            }
            env.update({k: None for k in self._env if k not in payload["env"]})
            reply = self.client.patch_scene(
                self.robot_id,
                upsert=[o for oid, o in objects.items() if self._objects.get(oid) != o],
                remove=[oid for oid in self._objects if oid not in objects],
                env=env,
            )
        if reply.hash != scene.hash:
            raise RuntimeError(f"the service holds scene {reply.hash}, not {scene.hash}")
        self._objects, self._env = objects, dict(payload["env"])
        self.scene_hash = scene.hash
        self.scene_updates += 1

    def plan(
        self, start: Iterable[float], goal: Iterable[float], options: dict[str, Any]
    ) -> tuple[PlanResult, float]:
        """Ask for a plan; the answer and the client-side wall time (ms)."""
        start, goal = [float(v) for v in start], [float(v) for v in goal]
        began = time.perf_counter()
        try:
            answer = self.client.plan(self.robot_id, start, goal, options)
        except APIError as exc:
            raise RuntimeError(f"plan answered {exc.status_code}: {exc.detail[:400]}") from exc
        return answer, (time.perf_counter() - began) * 1e3

    def call(self, run: CleaningRun, call: PlanCall, options: dict[str, Any]) -> CallRecord:
        """Bring the scene up to date for `call`, plan it and record the answer."""
        self.show(run.scene_for(call))
        answer, wall_ms = self.plan(call.start, call.goal, options)
        states = answer.states
        return CallRecord(
            index=call.index,
            label=call.label,
            base_moves=call.base_moves,
            start=call.start,
            goal=call.goal,
            scene_hash=self.scene_hash,
            status=answer.status,
            source=answer.source,
            trajectory_id=answer.trajectory_id,
            candidates_tried=answer.candidates_tried,
            timings={
                **{k: 0.0 for k in TIMING_KEYS},
                **{k: float(v) for k, v in answer.timings_ms.items()},
            },
            wall_ms=wall_ms,
            states=None if states is None else np.asarray(states, dtype=float),
            rejected=[r.model_dump() for r in answer.rejected],
            message=answer.message,
        )

    def play(
        self, run: CleaningRun, options: dict[str, Any], limit: int | None = None
    ) -> list[CallRecord]:
        """Play the calls of `run` (the first `limit`) in order."""
        return [self.call(run, call, options) for call in run.calls[:limit]]
