"""Safety soak: random scene changes interleaved with plan requests; no returned path may collide.

Starts `trajcache serve` (uvicorn on loopback, a temporary SQLite database) with the reference
robot in the restroom (REFERENCE.md).

- Warm-up: a robot plays cleaning run S (its first 40 calls with --smoke), so the cache holds
  many trajectories.
- Soak: a second robot, whose scene keeps changing, sends --plans plan requests. Before each
  request the scene changes with probability 1/2, again and again (PATCH; the service's hash must
  equal the local scene's): a door swung to a random angle, a seat raised or lowered, a small
  fixture shifted by up to 3 cm or an added object moved anywhere, clutter added (on the floor
  or in the air) or removed. Requests are calls of cleaning run S+1 (mostly hits), random pairs
  of task configurations at a station, drives between stations, and blocked requests. The ones
  that are not blocked draw their options: default, `match: "arm"` (a motion cached at one base
  pose serving another) or a wide lookup (threshold 0.4, 5 candidates).
- Blocked requests: a cached trajectory (the one last returned, else a random one of the cache)
  is fetched with GET /v1/trajectories/{id}; at the dense sample and robot primitive farthest
  from the robot at the trajectory's endpoints, a sphere of radius 3–5 cm goes on that primitive
  ("deep"), or, for half of them, a few cm off it and just large enough (+1–4 mm) that the
  path reaches into it ("grazing"). The request is the trajectory's endpoints (maybe reversed)
  plus noise within the lookup threshold, so the lookup finds that trajectory. The sphere is kept
  only if the request's start and goal are free (no 422) and the path adapted to the request
  collides; it counts as confirmed when the stored trajectory, unchanged, collides in the new
  scene. Half of these spheres are removed right after their request.

Every trajectory returned (hits and planned) is checked by the independent dense check
(harness.dense: plain FCL, steps 4× finer than the paper's, no padding) in the scene in
force at its call. `unsafe` counts answers it finds in collision or out of joint limits, or that do
not run from the request's start to its goal; --dump writes each one's scene and request as JSON.
Exits 1 when unsafe > 0 or the service answered 5xx.

    python bench/safety_soak.py [--plans N] [--seed S] [--smoke] [--dump PATH]

Prints a table; the last line is one JSON object with `plans` and `unsafe`.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.dense import DenseChecker, reference_checker
from harness.replay import RobotClient, cached_count
from harness.service import running_service
from soak_geometry import (
    grazing_radius,
    judge,
    path_obstacle,
    sphere,
)
from soak_report import print_table
from soak_scene import CHANGE_KINDS, SceneChanger, SoakRobot
from trajcache.cache.adapt import adapt_trajectory
from trajcache.cache.metric import wrap_angle
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.model.space import base_is_still
from trajcache.geometry.scene.payload import apply_patch, scene_to_payload
from trajcache.reference.cleaning import PlanCall, cleaning_run
from trajcache.reference.restroom import restroom_scene
from trajcache.reference.robot import REFERENCE_BASE, reference_model, reference_urdf
from trajcache.reference.tasks import STOW, TASKS, work_stations
from trajcache_client import NO_RETRY, APIError, Client

SMOKE_PLANS, SMOKE_WARM = 50, 40
OPTIONS: dict[str, Any] = {"fallback": True}  # warm-up and blocked requests
VARIANTS: dict[str, dict[str, Any]] = {  # the other requests draw one of these
    "default": OPTIONS,
    "arm": {"fallback": True, "match": "arm"},  # the base may stand elsewhere than cached
    "wide": {"fallback": True, "threshold": 0.4, "max_candidates": 5},  # more adaptation
}
BLOCKED_SHARE, RUN_SHARE = 0.3, 0.35  # the rest: task pairs and drives
GRAZING_SHARE = 0.5  # of path obstacles: only just reaching into the path, not on a link


@dataclass
class Request:
    """One plan request of the soak; `target` is the blocked trajectory of a blocked request."""

    kind: str  # "run", "task", "drive" or "blocked"
    start: FloatArray
    goal: FloatArray
    target: int | None = None
    grazing: bool = False  # a blocked request whose obstacle only just reaches into the path
    options: str = "default"  # a key of VARIANTS


class Soak:
    """Interleaves scene changes and plan requests against one robot, tallying the answers."""

    def __init__(self, robot: SoakRobot, checker: DenseChecker, seed: int, model_id: str) -> None:
        self.robot, self.checker, self.model_id = robot, checker, model_id
        self.rng = np.random.default_rng([seed, 7])
        self.changer = SceneChanger(robot, self.rng)
        self.run_calls: list[PlanCall] = cleaning_run(seed + 1).calls
        self.run_next = 0
        model = reference_model()
        self.lower, self.upper = model.lower + 1e-6, model.upper - 1e-6
        self.last_id: int | None = None
        self.tally: Counter[str] = Counter()
        self.contacts: Counter[str] = Counter()
        self.http_4xx: Counter[str] = Counter()  # first words of each kind of 4xx answer
        self.errors: list[str] = []
        self.unsafe_cases: list[dict[str, Any]] = []  # what reproduces each unsafe answer

    # --- scene changes -------------------------------------------------------------------

    # --- requests ------------------------------------------------------------------------

    def next_request(self) -> Request:
        """A blocked request, a call of cleaning run S+1, a task pair or a drive."""
        draw = self.rng.random()
        if draw < BLOCKED_SHARE:
            blocked = self._blocked()
            if blocked is not None:
                return blocked
            self.tally["blocked_skipped"] += 1
        elif draw < BLOCKED_SHARE + RUN_SHARE:
            call = self.run_calls[self.run_next % len(self.run_calls)]
            self.run_next += 1
            return Request("run", call.start, call.goal, options=self._variant())
        return self._task_pair()

    def _variant(self) -> str:
        return str(self.rng.choice(list(VARIANTS)))

    def _noisy(self, base: Any, arm: Any, base_noise: FloatArray | None = None) -> FloatArray:
        if base_noise is None:
            base_noise = self.rng.uniform(-0.02, 0.02, 3)
        arm_noise = self.rng.uniform(-0.02, 0.02, 7)
        state = np.concatenate([np.asarray(base, float) + base_noise, np.asarray(arm) + arm_noise])
        state[2] = wrap_angle(state[2])  # the heading wraps
        return np.clip(state, self.lower, self.upper)

    def _task_pair(self) -> Request:
        stations = work_stations()
        if self.rng.random() < 0.25:
            a, b = self.rng.choice(len(stations), 2, replace=False)
            start = self._noisy(stations[a].pose, STOW)
            goal = self._noisy(stations[b].pose, STOW)
            return Request("drive", start, goal, options=self._variant())
        station = stations[int(self.rng.integers(len(stations)))]
        tasks = list(TASKS[station.kind])
        a, b = self.rng.choice(len(tasks), 2, replace=False)
        noise = self.rng.uniform(-0.02, 0.02, 3)  # the base stays where it is
        arm = TASKS[station.kind]
        start = self._noisy(station.pose, arm[tasks[a]], noise)
        goal = self._noisy(station.pose, arm[tasks[b]], noise)
        return Request("task", start, goal, options=self._variant())

    def _candidates(self) -> list[int]:
        page = self.robot.client.list_trajectories(model_id=self.model_id, limit=1000)
        ids = [item.trajectory_id for item in page.items]
        picks = [ids[int(i)] for i in self.rng.permutation(len(ids))[:6]]
        return ([self.last_id] if self.last_id is not None else []) + picks

    def _blocked(self) -> Request | None:
        """Put a sphere into the path of a cached trajectory; the request its endpoints make."""
        for tid in self._candidates():
            try:
                trajectory = self.robot.client.get_trajectory(tid)
            except APIError:  # deleted meanwhile
                continue
            stored = np.asarray(trajectory.states, dtype=float)
            reverse = bool(self.rng.random() < 0.25)
            first, last = (stored[-1], stored[0]) if reverse else (stored[0], stored[-1])
            base_noise = self.rng.uniform(-0.01, 0.01, 3)
            still = base_is_still(first, last, BaseType.PLANAR)
            start = self._noisy(first[:3], first[3:], base_noise)
            goal = self._noisy(last[:3], last[3:], base_noise if still else None)
            placed = self._obstacle_for(stored, start, goal, reverse)
            if placed is None:
                continue
            obstacle, grazing = placed
            self.changer.add(obstacle, "path_obstacle")
            scene = self.robot.scene  # the new scene, as the service holds it
            confirmed = self.checker.check(stored, scene.hash, scene_to_payload(scene)).collides
            self.tally["blocked_candidates_confirmed"] += confirmed
            self.tally["path_obstacles_grazing"] += grazing
            return Request("blocked", start, goal, target=tid, grazing=grazing)
        return None

    def _obstacle_for(
        self, stored: FloatArray, start: FloatArray, goal: FloatArray, reverse: bool
    ) -> tuple[dict[str, Any], bool] | None:
        """A sphere that the stored path and its adaptation to the request run into, clear of
        the request's start and goal, and whether it only grazes the paths."""
        oid = f"obstacle_{self.changer.added}"
        obstacle = path_obstacle(self.checker, stored, oid, self.rng)
        if obstacle is None:
            return None
        path = adapt_trajectory(stored, start, goal, base=BaseType.PLANAR, reverse=reverse)
        grazing = bool(self.rng.random() < GRAZING_SHARE)
        if grazing:  # moved off the link, then grown until both paths just reach into it
            direction = self.rng.normal(size=3)
            offset = float(self.rng.uniform(0.03, 0.07))
            centre = np.asarray(obstacle["pose"]["position"])
            centre = centre + offset * direction / np.linalg.norm(direction)
            radius = grazing_radius(self.checker, [stored, path], centre, offset + 0.05)
            if radius is None:
                return None
            obstacle = sphere(oid, centre, radius + float(self.rng.uniform(0.001, 0.004)))
        trial = apply_patch(self.robot.scene, {"upsert": [obstacle]})
        payload = scene_to_payload(trial)
        for state in (start, goal):  # else the request would be a 422
            if self.checker.check(np.stack([state]), trial.hash, payload).collides:
                return None
        if not self.checker.check(path, trial.hash, payload).collides:
            return None  # the request's noise took the adapted path off the sphere
        return obstacle, grazing

    # --- answers -------------------------------------------------------------------------

    def request(self, req: Request) -> None:
        """Send `req` in the current scene and tally the answer and its dense check."""
        t = self.tally
        t["plans"] += 1
        t[f"plans_{req.kind}"] += 1
        t[f"options_{req.options}"] += 1
        code, answer = self.robot.ask(req.start, req.goal, VARIANTS[req.options])
        if code >= 500:
            t["http_5xx"] += 1
            self.errors.append(f"{code}: {str(answer)[:300]}")
            return
        if code >= 400:
            t["http_4xx"] += 1
            t[f"http_4xx_{req.kind}"] += 1
            detail = re.sub(r"_\d+", "_N", str(answer.get("detail")))  # clutter_N, not each id
            self.http_4xx[f"{code}: {detail[:80]}"] += 1
            return
        rejected = {int(r["trajectory_id"]) for r in answer.get("rejected") or []}
        if req.target is not None:
            t["blocked_target_rejected"] += req.target in rejected
        if answer["status"] != "success":
            t["failed"] += 1
            t[f"failed_{req.kind}"] += 1
            return
        hit = answer["source"] == "cache"
        t["hits" if hit else "planned"] += 1
        if req.target is not None and hit:
            t["blocked_hits"] += 1
            t["blocked_hits_target"] += answer["trajectory_id"] == req.target
            t["blocked_hits_grazing"] += req.grazing
        self.last_id = answer.get("trajectory_id")
        states = np.asarray(answer["states"], dtype=float)
        verdict = judge(self.checker, self.robot.scene, states, req.start, req.goal)
        t["dense_samples"] += verdict.samples
        t["collisions"] += verdict.collides
        t["limit_violations"] += verdict.out_of_limits
        t["endpoint_errors"] += verdict.misjoined
        t["unsafe"] += verdict.unsafe
        if verdict.unsafe:
            t[f"unsafe_{req.kind}"] += 1
            self.contacts.update(verdict.contacts)
            self.errors.append(
                f"unsafe {req.kind} answer (source {answer['source']}, trajectory "
                f"{answer['trajectory_id']}, scene {self.robot.scene.hash}): {verdict}"
            )
            self.unsafe_cases.append(
                {
                    "scene": scene_to_payload(self.robot.scene),
                    "start": req.start.tolist(),
                    "goal": req.goal.tolist(),
                    "options": VARIANTS[req.options],
                    "answer": answer,
                    "verdict": str(verdict),
                }
            )


def soak(plans: int, warm_calls: int | None, seed: int) -> dict[str, Any]:
    """Run the soak against a fresh service; its figures."""
    began = time.perf_counter()
    checker = reference_checker()
    with running_service() as base, Client(base, timeout=120, retry=NO_RETRY) as client:
        model = client.register_model(reference_urdf(), base=REFERENCE_BASE, name="soak")
        model_id = model.model_id
        warm = RobotClient(client, "soak-warm", model_id, "sim")
        warm_run = cleaning_run(seed)
        records = warm.play(warm_run, OPTIONS, warm_calls)
        cached_warm = cached_count(client, model_id)
        robot = SoakRobot(client, "soak", model_id, restroom_scene())
        run = Soak(robot, checker, seed, model_id)
        soak_began = time.perf_counter()
        while run.tally["plans"] < plans:
            while run.rng.random() < 0.5:
                run.changer.change()
            request = run.next_request()
            run.request(request)
            if request.kind == "blocked" and run.rng.random() < 0.5:
                run.changer.remove(run.changer.extras[-1])  # the obstacle has done its work
        soak_s = time.perf_counter() - soak_began
        cached_end = cached_count(client, model_id)
    t = run.tally
    return {
        "plans": t["plans"],
        "unsafe": t["unsafe"],
        "collisions": t["collisions"],
        "limit_violations": t["limit_violations"],
        "endpoint_errors": t["endpoint_errors"],
        "hits": t["hits"],
        "planned": t["planned"],
        "failed": t["failed"],
        "http_4xx": t["http_4xx"],
        "http_5xx": t["http_5xx"],
        "plans_by_options": {k: t[f"options_{k}"] for k in VARIANTS},
        "plans_by_kind": {k: t[f"plans_{k}"] for k in ("run", "task", "drive", "blocked")},
        "failed_by_kind": {k: t[f"failed_{k}"] for k in ("run", "task", "drive", "blocked")},
        "http_4xx_by_kind": {k: t[f"http_4xx_{k}"] for k in ("run", "task", "drive", "blocked")},
        "path_obstacles": robot.changes["path_obstacle"],
        "path_obstacles_grazing": t["path_obstacles_grazing"],
        "blocked_candidates_confirmed": t["blocked_candidates_confirmed"],
        "blocked_target_rejected": t["blocked_target_rejected"],
        "blocked_hits": t["blocked_hits"],
        "blocked_hits_target": t["blocked_hits_target"],
        "blocked_hits_grazing": t["blocked_hits_grazing"],
        "blocked_skipped": t["blocked_skipped"],
        "scene_changes": {k: robot.changes[k] for k in (*CHANGE_KINDS, "path_obstacle")},
        "warm_calls": len(records),
        "warm_hits": sum(r.hit for r in records),
        "cached_after_warm": cached_warm,
        "cached_end": cached_end,
        "dense_samples": t["dense_samples"],
        "soak_s": round(soak_s, 1),
        "wall_s": round(time.perf_counter() - began, 1),
        "seed": seed,
        "http_4xx_examples": dict(run.http_4xx.most_common(3)),
        "errors": run.errors[:10],
        "unsafe_cases": run.unsafe_cases,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the soak, print the table and the JSON line; 1 when anything was unsafe."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--plans", type=int, help="plan requests (default 240; smoke 50)")
    parser.add_argument("--seed", type=int, default=1, help="workload and soak seed S")
    parser.add_argument("--smoke", action="store_true", help="a short run for CI")
    parser.add_argument("--dump", metavar="PATH", help="write unsafe cases (scene, request) here")
    args = parser.parse_args(argv)
    plans = args.plans or (SMOKE_PLANS if args.smoke else 240)
    figures = soak(plans, SMOKE_WARM if args.smoke else None, args.seed)
    cases = figures.pop("unsafe_cases")
    if cases and args.dump:
        with open(args.dump, "w") as out:
            json.dump(cases, out)
    print_table(figures)
    print(json.dumps({**figures, "smoke": args.smoke}))
    return 1 if figures["unsafe"] or figures["http_5xx"] else 0


if __name__ == "__main__":
    sys.exit(main())
