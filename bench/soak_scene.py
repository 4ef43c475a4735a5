"""bench/safety_soak.py's scene changes: the soak robot's scene, changed by patches at random.

A door swung to a random angle, a seat raised or lowered, a small fixture shifted by up to 3 cm
or an added object moved anywhere, clutter added (on the floor or in the air) or removed. Each
change is applied locally and at the service, whose scene hash must equal the local one.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from harness.replay import RobotClient
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.payload import apply_patch, object_to_payload
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.restroom import STALL_COUNT, restroom_scene
from trajcache_client import APIError, Client

CHANGE_KINDS = ("door", "seat", "move", "add", "remove")
CHANGE_WEIGHTS = (0.3, 0.1, 0.25, 0.2, 0.15)
MOVABLE = (
    *("trash_bin", "hand_dryer", "sink_1_soap", "sink_2_soap"),
    *(f"stall_{i}_{part}" for i in range(1, STALL_COUNT + 1) for part in ("bin", "paper_holder")),
)  # small fixtures that the soak shifts by a few cm
BOX_FACES = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]  # fmt: skip
MAX_EXTRAS = 10  # added objects (clutter and path obstacles) kept at once


class SoakRobot(RobotClient):
    """The soak's robot: its scene is changed by patches, applied here and at the service."""

    def __init__(self, client: Client, robot_id: str, model_id: str, scene: Scene) -> None:
        super().__init__(client, robot_id, model_id, "real")
        self.show(scene)
        self.scene = scene
        self.changes: Counter[str] = Counter()

    def patch(self, patch: dict[str, Any], kind: str) -> None:
        """Apply `patch` locally and at the service; both must hold the same scene."""
        scene = apply_patch(self.scene, patch)
        reply = self.client.patch_scene(
            self.robot_id,
            upsert=patch.get("upsert", ()),
            remove=patch.get("remove", ()),
            env=patch.get("env"),
        )
        if reply.hash != scene.hash:
            raise RuntimeError(f"the service holds scene {reply.hash}, not {scene.hash}")
        self.scene, self.scene_hash = scene, scene.hash
        self.changes[kind] += 1

    def ask(
        self, start: FloatArray, goal: FloatArray, options: dict[str, Any]
    ) -> tuple[int, dict[str, Any]]:
        """Ask for a plan; the HTTP status and the answer as JSON (4xx/5xx: their detail)."""
        start_values, goal_values = [float(v) for v in start], [float(v) for v in goal]
        try:
            answer = self.client.plan(self.robot_id, start_values, goal_values, options)
        except APIError as exc:
            return exc.status_code, {"detail": exc.detail[:300]}
        return 200, answer.model_dump(mode="json")


class SceneChanger:
    """Random changes to the robot's scene; keeps the doors, seats, fixtures and added objects."""

    def __init__(self, robot: SoakRobot, rng: np.random.Generator) -> None:
        self.robot, self.rng = robot, rng
        self.doors = [0.0] * STALL_COUNT
        self.seats = [0.0] * STALL_COUNT
        self.fixtures = {o.id: o.pose for o in robot.scene.objects if o.id in MOVABLE}
        self.extras: list[str] = []
        self.added = 0

    def change(self) -> None:
        """One random scene change (PATCH)."""
        kind = str(self.rng.choice(CHANGE_KINDS, p=CHANGE_WEIGHTS))
        if kind == "remove" and not self.extras:
            kind = "add"
        k = int(self.rng.integers(STALL_COUNT))
        if kind == "door":
            angle = self.rng.choice([0.0, 90.0, round(float(self.rng.uniform(0.0, 90.0)), 1)])
            self.doors[k] = float(angle)  # closed, wide open or in between
            self._restroom_part(k, ("stall_{i}_door", "stall_{i}_door_handle"), "door")
        elif kind == "seat":
            self.seats[k] = 90.0 if self.seats[k] == 0.0 else 0.0
            self._restroom_part(k, ("toilet_{i}_seat",), "seat")
        elif kind == "move":
            self._move()
        elif kind == "add":
            self.add(self.clutter(f"clutter_{self.added}"), "add")
        else:
            self.remove(self.extras[int(self.rng.integers(len(self.extras)))])

    def remove(self, oid: str) -> None:
        """Remove an added object."""
        self.extras.remove(oid)
        self.robot.patch({"remove": [oid]}, "remove")

    def _restroom_part(self, k: int, ids: tuple[str, ...], kind: str) -> None:
        full = restroom_scene(doors=self.doors, seats=self.seats)
        wanted = {p.format(i=k + 1) for p in ids}
        upsert = [object_to_payload(o) for o in full.objects if o.id in wanted]
        env_key = f"stall_{k + 1}_{kind}"
        self.robot.patch({"upsert": upsert, "env": {env_key: full.env[env_key]}}, kind)

    def _move(self) -> None:
        names = [*self.fixtures, *self.extras]
        oid = names[int(self.rng.integers(len(names)))]
        current = next(o for o in self.robot.scene.objects if o.id == oid)
        payload = object_to_payload(current)
        if oid in self.fixtures:  # a fixture shifts a little from where it belongs
            shift = self.rng.uniform(-0.03, 0.03, 2)
            payload["pose"]["position"][:2] = (self.fixtures[oid][:2, 3] + shift).tolist()
        else:
            payload["pose"] = self.clutter(oid)["pose"]
        self.robot.patch({"upsert": [payload]}, "move")

    def clutter(self, oid: str) -> dict[str, Any]:
        """A random object, turned any way: on the floor (a bucket, a mop) or in the air."""
        kind = str(self.rng.choice(["box", "cylinder", "capsule", "sphere", "mesh"]))
        u = self.rng.uniform
        size: FloatArray = {"box": u(0.08, 0.3, 3), "cylinder": u([0.04, 0.1], [0.15, 0.5]),
                            "capsule": u([0.015, 0.2], [0.05, 0.8]), "sphere": u(0.04, 0.12, 1),
                            "mesh": u(0.08, 0.3, 3)}[kind]  # fmt: skip
        reach = float(np.linalg.norm(size)) / 2  # about its bounding radius
        x, y = self.rng.uniform(0.3, 5.7), self.rng.uniform(0.3, 3.7)
        z = reach if self.rng.random() < 0.6 else self.rng.uniform(0.5, 1.5)
        turn = self.rng.normal(size=4)
        obj: dict[str, Any] = {"id": oid, "type": kind}
        if kind == "mesh":  # a box as 12 triangles
            corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
            obj["vertices"] = (corners * size / 2).round(4).tolist()
            obj["faces"] = BOX_FACES
        else:
            obj["size"] = [round(float(v), 4) for v in size]
        obj["pose"] = {
            "position": [x, y, float(z)],
            "orientation": [float(v) for v in turn / np.linalg.norm(turn)],
        }
        return obj

    def add(self, obj: dict[str, Any], kind: str) -> None:
        """Add `obj`, removing the oldest added object when MAX_EXTRAS are there."""
        upsert, remove = [obj], []
        if len(self.extras) >= MAX_EXTRAS:
            remove.append(self.extras.pop(0))
        self.robot.patch({"upsert": upsert, "remove": remove}, kind)
        self.extras.append(obj["id"])
        self.added += 1
