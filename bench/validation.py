"""Validation throughput: a naive per-state FCL manager loop against the project's validator.

Reference robot in the restroom scene. Both checkers run over the same interpolated samples of
collision-free trajectories (every sample checked) and of trajectories that collide late (both
stop at the first collision); a third row takes the motions of a reference cleaning run (start
to goal of each call whose straight motion is free, in that call's scene: what the cache mostly
holds). "certified ms" is the validator's time per trajectory, what a cache hit pays. Verdicts
are compared state by state, without padding, over random states. The last line printed is
one JSON object.

    python bench/validation.py            # full size
    python bench/validation.py --smoke    # seconds, for CI
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable

import fcl
import numpy as np

from trajcache.geometry.collision import COLLIDING, CollisionChecker
from trajcache.geometry.kinematics import element_transforms, link_transforms
from trajcache.geometry.reference.restroom import restroom_layout, restroom_scene
from trajcache.geometry.reference.robot import reference_model
from trajcache.geometry.robot import RobotModel
from trajcache.geometry.scene import Scene
from trajcache.geometry.validation import Resolution, TrajectoryValidator, interpolate
from trajcache.workload.cleaning import cleaning_run


class NaiveChecker:
    """The obvious implementation: for each state, move every FCL object and ask the managers."""

    def __init__(self, model: RobotModel, scene: Scene) -> None:
        self.model = model
        self.geoms = [e.shape.to_fcl() for e in model.elements]
        self.objs = [fcl.CollisionObject(g, fcl.Transform()) for g in self.geoms]
        self.link_of = {id(g): e.link for g, e in zip(self.geoms, model.elements, strict=True)}
        self.robot = fcl.DynamicAABBTreeCollisionManager()
        self.robot.registerObjects(self.objs)
        self.robot.setup()
        self.scene = fcl.DynamicAABBTreeCollisionManager()
        self.scene.registerObjects(
            [
                fcl.CollisionObject(o.shape.to_fcl(), fcl.Transform(o.pose[:3, :3], o.pose[:3, 3]))
                for o in scene.objects
            ]
        )
        self.scene.setup()

    def state_collides(self, state: np.ndarray) -> bool:
        """Per-state check: FK of one state, update the manager, scene then self collisions."""
        poses = element_transforms(self.model, link_transforms(self.model, state[None, :]))[0]
        for obj, pose in zip(self.objs, poses, strict=True):
            obj.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
        self.robot.update()
        data = fcl.CollisionData(request=fcl.CollisionRequest())
        self.robot.collide(self.scene, data, fcl.defaultCollisionCallback)
        if data.result.is_collision:
            return True
        request = fcl.CollisionRequest(num_max_contacts=100_000, enable_contact=True)
        data = fcl.CollisionData(request=request)
        self.robot.collide(data, fcl.defaultCollisionCallback)
        for contact in data.result.contacts:
            a, b = self.link_of[id(contact.o1)], self.link_of[id(contact.o2)]
            if a != b and (min(a, b), max(a, b)) not in self.model.allowed_pairs:
                return True
        return False

    def validate(self, samples: np.ndarray) -> bool:
        """True when every sample is free; stops at the first collision."""
        return not any(self.state_collides(s) for s in samples)


def random_states(model: RobotModel, rng: np.random.Generator, count: int) -> np.ndarray:
    """States at the restroom's stations with random arm configurations."""
    stations = np.array([s.pose for s in restroom_layout().stations])
    base = stations[rng.integers(len(stations), size=count)]
    base = base + rng.normal(0.0, [0.05, 0.05, 0.05], size=base.shape)
    off = model.arm_offset
    arm = rng.uniform(model.lower[off:], model.upper[off:], size=(count, model.dof - off))
    return np.hstack([base, arm])


def make_trajectories(
    model: RobotModel, checker: CollisionChecker, rng: np.random.Generator, count: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Collision-free trajectories (every sample free) and trajectories that collide late."""
    free: list[np.ndarray] = []
    late: list[np.ndarray] = []
    pool = random_states(model, rng, 4000)
    ok = checker.check(pool, stop_at_first=False).status != COLLIDING
    good, bad = pool[ok], pool[~ok]
    while len(free) < count or len(late) < count:
        start = good[rng.integers(len(good))]
        key = [start]
        for _ in range(3):
            nxt = start.copy()
            nxt[3:] += rng.normal(0.0, 0.35, size=model.dof - 3)
            nxt[3:] = np.clip(nxt[3:], model.lower[3:], model.upper[3:])
            key.append(nxt)
        key_arr = np.array(key)
        samples = interpolate(key_arr, model, Resolution())
        if not (checker.check(samples).first_collision >= 0):
            if len(free) < count:
                free.append(key_arr)
            target = bad[rng.integers(len(bad))].copy()
            target[:3] = key_arr[-1, :3]
            tail = np.vstack([key_arr, target])
            tail_samples = interpolate(tail, model, Resolution())
            hit = checker.check(tail_samples).first_collision
            if hit >= 0.8 * len(tail_samples) and len(late) < count:
                late.append(tail)
    return free, late


def workload_motions(
    model: RobotModel, seed: int, count: int
) -> list[tuple[np.ndarray, TrajectoryValidator, TrajectoryValidator, NaiveChecker]]:
    """Free straight motions of a cleaning run, each with the checkers of its call's scene."""
    run = cleaning_run(seed)
    by_scene: dict[str, tuple[TrajectoryValidator, TrajectoryValidator, NaiveChecker]] = {}
    motions = []
    for call in run.calls:
        scene = run.scene_for(call)
        if scene.hash not in by_scene:
            by_scene[scene.hash] = (
                TrajectoryValidator(model, scene, certified=True),
                TrajectoryValidator(model, scene, certified=False),
                NaiveChecker(model, scene),
            )
        certified, plain, naive = by_scene[scene.hash]
        key = np.stack([call.start, call.goal])
        if certified.validate(key).valid:
            motions.append((key, certified, plain, naive))
        if len(motions) == count:
            break
    return motions


def timed(fns: list[Callable[[], object]], repeats: int) -> list[float]:
    """Median wall time of each of `fns` in seconds, taking turns so that a change in the
    machine's load hits them alike."""
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(repeats):
        for fn, spent in zip(fns, times, strict=True):
            began = time.perf_counter()
            fn()
            spent.append(time.perf_counter() - began)
    return [statistics.median(t) for t in times]


def main() -> None:
    """Run the benchmark and print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="tiny run for CI")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    n_traj, n_states, repeats = (4, 1000, 1) if args.smoke else (30, 10_000, 3)

    rng = np.random.default_rng(args.seed)
    model = reference_model()
    scene = restroom_scene(doors=[30.0, 60.0, 90.0])
    checker = CollisionChecker(model, scene)
    naive = NaiveChecker(model, scene)
    free, late = make_trajectories(model, checker, rng, n_traj)
    certified = TrajectoryValidator(model, scene, certified=True)
    plain = TrajectoryValidator(model, scene, certified=False)

    rows = []
    figures: dict[str, float] = {}
    for label, trajs in (("collision-free", free), ("collides late", late)):
        samples = [interpolate(k, model, Resolution()) for k in trajs]
        total = sum(len(s) for s in samples)
        t_naive, t_plain, t_cert = timed(
            [
                lambda s=samples: [naive.validate(x) for x in s],
                lambda t=trajs: [plain.validate(k) for k in t],
                lambda t=trajs: [certified.validate(k) for k in t],
            ],
            repeats,
        )
        rows.append((label, len(trajs), total, t_naive, t_plain, t_cert))
    motions = workload_motions(model, args.seed, n_traj * 3)
    samples = [interpolate(k, model, Resolution()) for k, *_ in motions]
    t_naive, t_plain, t_cert = timed(
        [
            lambda: [m[3].validate(x) for m, x in zip(motions, samples, strict=True)],
            lambda: [p.validate(k) for k, _, p, _ in motions],
            lambda: [c.validate(k) for k, c, _, _ in motions],
        ],
        repeats,
    )
    rows.append(("workload", len(motions), sum(len(x) for x in samples), t_naive, t_plain, t_cert))
    for label, count, total, t_naive, t_plain, t_cert in rows:
        figures[label] = total / t_naive
        figures[label + "/plain"] = total / t_plain
        figures[label + "/certified"] = total / t_cert
        figures[label + "/ms"] = t_cert / count * 1e3

    states = random_states(model, rng, n_states)
    began = time.perf_counter()
    naive_verdict = np.array([naive.state_collides(s) for s in states])
    t_naive_states = time.perf_counter() - began
    began = time.perf_counter()
    ours = checker.check(states, stop_at_first=False).status == COLLIDING
    t_ours_states = time.perf_counter() - began
    mismatches = int(np.sum(naive_verdict != ours))

    print(
        f"{'trajectories':<16}{'count':>6}{'states':>8}{'naive st/s':>12}{'plain st/s':>12}"
        f"{'certified st/s':>16}{'ratio':>8}{'certified ms':>14}"
    )
    for label, count, total, *_ in rows:
        a, c = figures[label], figures[label + "/certified"]
        print(
            f"{label:<16}{count:>6}{total:>8}{a:>12.0f}{figures[label + '/plain']:>12.0f}"
            f"{c:>16.0f}{c / a:>8.2f}{figures[label + '/ms']:>14.2f}"
        )
    print(
        f"random states: {n_states}, colliding {int(ours.sum())}, mismatches {mismatches}; "
        f"per-state batch check {n_states / t_ours_states:.0f} st/s vs naive "
        f"{n_states / t_naive_states:.0f} st/s"
    )
    result = {
        "naive_states_per_s": round(figures["collision-free"], 1),
        "validator_states_per_s": round(figures["collision-free/certified"], 1),
        "validator_plain_states_per_s": round(figures["collision-free/plain"], 1),
        "ratio": round(figures["collision-free/certified"] / figures["collision-free"], 2),
        "ratio_plain": round(figures["collision-free/plain"] / figures["collision-free"], 2),
        "ratio_late": round(figures["collides late/certified"] / figures["collides late"], 2),
        "ratio_workload": round(figures["workload/certified"] / figures["workload"], 2),
        "validator_ms_per_trajectory": round(figures["collision-free/ms"], 3),
        "workload_ms_per_trajectory": round(figures["workload/ms"], 3),
        "mismatches": mismatches,
        "verdict_states": n_states,
        "smoke": args.smoke,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
