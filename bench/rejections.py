"""What a rejected cached candidate costs a plan request, and what explaining it costs off the path.

The reference robot in the restroom (cleaning run S). Each arm motion of the run that a 9 cm
box at the end effector, halfway along, blocks (the motion free without it, its ends clear with
it) is stored as a trajectory. Then, round after round, each is asked for by two robots in
turn, with its ends moved by up to 1 mrad per arm joint every time (a fresh request: no
validation memo helps):

- `hit`: a robot in the motion's scene. The candidate is validated and served.
- `rejected`: a robot in the scene with the box. The candidate is validated and rejected; with
  no fallback the answer is a miss, and its plan event records why (the first failing sample,
  the link and the box).

Server timings come from each answer (`timings_ms`). `explain` is what the record writer spends,
off the request path, on one rejection: placing the failing state on the path's samples and
asking for every contact there (`services.bookkeeping.rejections.rejection_entries`), measured in
process on the same candidates. A request that explained its own rejections would pay it before
answering. The last line printed is one JSON object.

    python bench/rejections.py [--smoke] [--rounds N] [--seed S]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from fastapi.testclient import TestClient

from trajcache.core.config import Settings
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.path_quality import end_effector_link
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator, ValidationStatus
from trajcache.main import create_app
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.robot import reference_urdf
from trajcache.services.bookkeeping.rejections import RejectedCandidate, rejection_entries

BOX = 0.09  # m, the side of the box put in a stored path's way


def _blocked(model: RobotModel, scene: Scene, path: np.ndarray) -> Scene | None:
    """`scene` with a box at the end effector halfway along `path`, if the path is free in
    `scene`, and the box blocks it and leaves its ends clear; None otherwise."""
    if TrajectoryValidator(model, scene).validate(path).status is not ValidationStatus.VALID:
        return None
    tip = link_transforms(model, (path[0] + path[-1]) / 2.0)[0][end_effector_link(model)]
    pose = np.eye(4)
    pose[:3, 3] = tip[:3, 3]
    box = SceneObject("cart", Shape(ShapeKind.BOX, (BOX,) * 3), pose)
    scene = make_scene([*scene.objects, box], scene.env)
    validator = TrajectoryValidator(model, scene)
    if any(validator.checker.state_contacts(s) for s in (path[0], path[-1])):
        return None
    return scene if validator.validate(path).status is ValidationStatus.COLLISION else None


def _ok(reply: Any) -> Any:
    assert reply.status_code < 300, reply.text
    return reply.json()


def _p50(values: list[float]) -> float:
    return round(float(np.median(values)), 3) if values else float("nan")


Case = tuple[np.ndarray, Scene, Scene]  # a stored path, its scene, the scene with the box


@dataclass
class Answers:
    """The timed answers by kind ("hit" or "rejected"), and the cases left out."""

    timings: dict[str, list[float]] = field(default_factory=lambda: {"hit": [], "rejected": []})
    validate: dict[str, list[float]] = field(default_factory=lambda: {"hit": [], "rejected": []})
    tried: dict[str, list[float]] = field(  # candidates rejected per answer
        default_factory=lambda: {"hit": [], "rejected": []}
    )
    dropped: set[int] = field(default_factory=set)  # cases whose hit did not serve its candidate
    explained: int = 0  # plan events (latest misses) whose rejection names its pairs
    listed: int = 0


def blocked_cases(model: RobotModel, seed: int, smoke: bool) -> list[Case]:
    """The arm motions of cleaning run `seed` that the box blocks cleanly."""
    run = cleaning_run(seed)
    cases = []
    for call in run.calls:
        if call.base_moves:
            continue
        scene, path = run.scene_for(call), np.stack([call.start, call.goal])
        blocked = _blocked(model, scene, path)
        if blocked is not None:
            cases.append((path, scene, blocked))
    cases = cases[:2] if smoke else cases
    assert cases, "no arm motion of the run is blocked cleanly by the box"
    return cases


def _robots(client: TestClient, cases: list[Case]) -> list[tuple[str, str, np.ndarray]]:
    """Two robots per case, one in its scene and one in the blocked scene; (kind, id, path)."""
    body = {"urdf": reference_urdf(), "base": "planar"}
    model_id = _ok(client.post("/v1/robot-models", json=body))["model_id"]
    robots = []
    for k, (path, scene, blocked) in enumerate(cases):
        for kind, where in (("hit", scene), ("rejected", blocked)):
            robot = f"{kind}-{k}"
            _ok(client.put(f"/v1/robots/{robot}", json={"model_id": model_id}))
            _ok(client.put(f"/v1/robots/{robot}/scene", json=scene_to_payload(where)))
            robots.append((kind, robot, path))
        stored = {"model_id": model_id, "states": path.tolist(), "source": "sim"}
        _ok(client.post("/v1/trajectories", json=stored))
    return robots


def _ask_rounds(
    client: TestClient, robots: list[tuple[str, str, np.ndarray]], rounds: int, rng: Any
) -> Answers:
    """Each robot asks once per round; rounds after the first are timed."""
    answers = Answers()
    for r in range(rounds + 1):  # round 0 builds each robot's validator: not timed
        for k, (kind, robot, path) in enumerate(robots):
            if k // 2 in answers.dropped:
                continue
            # A fresh request each time (±1 mrad on the arm): no validation memo helps.
            ends = path[[0, -1]].copy()
            ends[:, 3:] += rng.uniform(-1e-3, 1e-3, ends[:, 3:].shape)
            plan = {"start": ends[0].tolist(), "goal": ends[1].tolist(),
                    "options": {"fallback": False}}  # fmt: skip
            answer = _ok(client.post(f"/v1/robots/{robot}/plan", json=plan))
            expected = "success" if kind == "hit" else "miss"
            if r == 0 and answer["status"] != expected:
                answers.dropped.add(k // 2)  # another stored motion came first, say
                continue
            assert answer["status"] == expected, (robot, answer["status"])
            if r > 0:
                answers.tried[kind].append(len(answer.get("rejected") or []))
                answers.timings[kind].append(answer["timings_ms"]["total"])
                answers.validate[kind].append(answer["timings_ms"]["validate"])
    return answers


def serve(cases: list[Case], rounds: int, rng: Any) -> Answers:
    """Store each case's path and ask for it in both scenes through the app, round by round."""
    with tempfile.TemporaryDirectory() as tmp:
        settings = Settings(
            database_url=f"sqlite:///{Path(tmp) / 'bench.db'}", worker_backend="none"
        )
        with TestClient(create_app(settings)) as client:
            answers = _ask_rounds(client, _robots(client, cases), rounds, rng)
            ctx = client.app.state.ctx  # type: ignore[attr-defined]
            ctx.records.flush()
            events = _ok(client.get("/v1/plan-events", params={"status": "miss", "limit": 1000}))
            answers.listed = len(events["items"])  # the latest misses: each explains its rejection
            answers.explained = sum(
                1 for e in events["items"] if (e["rejections"] or [{}])[0].get("pairs")
            )
    return answers


def time_explaining(
    model: RobotModel, cases: list[Case], dropped: set[int], rounds: int
) -> list[float]:
    """Milliseconds the writer spends explaining one rejected candidate, per case and round."""
    explain: list[float] = []
    for k, (path, _, blocked) in enumerate(cases):
        if k in dropped:
            continue
        validator = TrajectoryValidator(model, blocked)
        result = validator.validate(path)
        candidate = RejectedCandidate(1, False, path, result)
        for _ in range(max(3, rounds)):
            began = time.perf_counter()
            entries = rejection_entries(validator, path[0], path[-1], [candidate])
            explain.append(1e3 * (time.perf_counter() - began))
        assert entries[0]["pairs"], "the rejection names no pair"
    return explain


def report(args: argparse.Namespace, cases: list[Case], a: Answers, explain: list[float]) -> None:
    """Print the table and the JSON line."""
    rounds = args.rounds
    rows = [
        ("hit (served)", a.timings["hit"], a.validate["hit"], a.tried["hit"]),
        ("rejected (miss)", a.timings["rejected"], a.validate["rejected"], a.tried["rejected"]),
    ]
    print(f"{len(cases) - len(a.dropped)} blocked arm motions of cleaning run {args.seed} "
          f"({len(a.dropped)} others not served first), {rounds} rounds each")  # fmt: skip
    print(
        f"{'request':<18}{'n':>6}{'total p50 ms':>15}{'validate p50 ms':>18}{'rejected/answer':>17}"
    )
    for name, totals, checks, rejected in rows:
        mean = float(np.mean(rejected)) if rejected else float("nan")
        print(f"{name:<18}{len(totals):>6}{_p50(totals):>15.3f}{_p50(checks):>18.3f}{mean:>17.2f}")
    print(f"{'explain (writer)':<18}{len(explain):>6}{_p50(explain):>15.3f}")
    rejected_ms = _p50(a.timings["rejected"])
    inline = _p50(explain) * float(np.mean(a.tried["rejected"]))  # per miss, if it explained them
    print(f"explaining a miss's rejections inline would add {inline:.3f} ms "
          f"({100 * inline / (rejected_ms + inline):.0f} % of its answer)")  # fmt: skip
    print(
        f"plan events (latest misses) with their rejection explained: {a.explained} of {a.listed}"
    )
    figures = {
        "cases": len(cases) - len(a.dropped),
        "rounds": rounds,
        "hit_total_ms_p50": _p50(a.timings["hit"]),
        "rejected_total_ms_p50": rejected_ms,
        "explain_ms_p50": _p50(explain),
        "rejected_per_miss": round(float(np.mean(a.tried["rejected"])), 2),
        "explain_ms_per_miss": round(inline, 3),
        "explain_share_if_inline": round(inline / (rejected_ms + inline), 3),
        "events_explained": a.explained,
        "events_listed": a.listed,
        "smoke": args.smoke,
    }
    print(json.dumps(figures))


def main() -> None:
    """Run the benchmark: print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="tiny run for CI")
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    args.rounds = args.rounds or (2 if args.smoke else 5)
    model = load_robot_model(reference_urdf(), base="planar")
    cases = blocked_cases(model, args.seed, args.smoke)
    rng = np.random.default_rng(args.seed)
    answers = serve(cases, args.rounds, rng)
    explain = time_explaining(model, cases, answers.dropped, args.rounds)
    report(args, cases, answers, explain)


if __name__ == "__main__":
    main()
