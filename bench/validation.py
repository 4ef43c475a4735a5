"""Validation throughput: a naive per-state FCL manager loop against the project's validator.

Reference robot in the restroom scene. Both checkers run over the same interpolated samples of
collision-free trajectories (every sample checked) and of trajectories that collide late (both
stop at the first collision); a third row takes the motions of a reference cleaning run (start
to goal of each call whose straight motion is free, in that call's scene: what the cache mostly
holds). "certified ms" is the validator's time per trajectory, what a cache hit pays. Verdicts
are compared state by state, without padding, over random states.

The Panda rows (`validation_panda`) take the Panda of example-robot-data with its meshes through
seeded table, shelf, box and cage problems: straight, detour and grazing paths, the same
checkers, a naive loop that asks FCL only about the pairs it must check (on meshes the naive
loop above spends most of its time listing contacts of adjacent links), and an independent
dense check (Pinocchio and coal) of every path. `mismatches` counts the reference
robot's state mismatches plus the Panda's safety failures (`panda_mismatches`: a path the
validator accepts that collides); a rejected path the dense check finds free is counted in
`panda_conservative`, by reason. The last line printed is one JSON object; the exit status is 1
when a Panda path is a safety failure.

    python bench/validation.py                         # full size (10 problems per family)
    python bench/validation.py --smoke                 # seconds, for CI (1 per family)
    python bench/validation.py --panda-problems 3      # Panda problems per family
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

import validation_panda
from naive_fcl import NaiveChecker, timed
from trajcache.geometry.collision.checker import COLLIDING, CollisionChecker
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.validator import Resolution, TrajectoryValidator, interpolate
from trajcache.geometry.warm import warm
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.restroom import restroom_layout, restroom_scene
from trajcache.reference.robot import reference_model


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


Checkers = tuple[TrajectoryValidator, TrajectoryValidator, NaiveChecker, TrajectoryValidator]


def workload_motions(
    model: RobotModel, seed: int, count: int
) -> list[tuple[np.ndarray, TrajectoryValidator, TrajectoryValidator, NaiveChecker,
                TrajectoryValidator]]:  # fmt: skip
    """Free straight motions of a cleaning run, each with the checkers of its call's scene
    (certified, plain, naive, certified on numpy levels)."""
    run = cleaning_run(seed)
    by_scene: dict[str, Checkers] = {}
    motions = []
    for call in run.calls:
        scene = run.scene_for(call)
        if scene.hash not in by_scene:
            by_scene[scene.hash] = (
                TrajectoryValidator(model, scene, certified=True),
                TrajectoryValidator(model, scene, certified=False),
                NaiveChecker(model, scene),
                TrajectoryValidator(model, scene, certifier=CertifierOptions(compiled=False)),
            )
        certified, plain, naive, numpy = by_scene[scene.hash]
        key = np.stack([call.start, call.goal])
        if certified.validate(key).valid:
            motions.append((key, certified, plain, naive, numpy))
        if len(motions) == count:
            break
    return motions


# label, count, states; naive, plain, certified on numpy levels, certified (compiled) s
Row = tuple[str, int, int, float, float, float, float]


def reference_rows(
    model: RobotModel,
    scene: Scene,
    checker: CollisionChecker,
    naive: NaiveChecker,
    rng: np.random.Generator,
    seed: int,
    n_traj: int,
    repeats: int,
) -> list[Row]:
    """The reference robot's rows: collision-free, late-colliding and workload trajectories."""
    free, late = make_trajectories(model, checker, rng, n_traj)
    certified = TrajectoryValidator(model, scene, certified=True)
    plain = TrajectoryValidator(model, scene, certified=False)
    numpy = TrajectoryValidator(model, scene, certifier=CertifierOptions(compiled=False))
    rows = []
    for label, trajs in (("collision-free", free), ("collides late", late)):
        samples = [interpolate(k, model, Resolution()) for k in trajs]
        total = sum(len(s) for s in samples)
        t_naive, t_plain, t_numpy, t_cert = timed(
            [
                lambda s=samples: [naive.validate(x) for x in s],
                lambda t=trajs: [plain.validate(k) for k in t],
                lambda t=trajs: [numpy.validate(k) for k in t],
                lambda t=trajs: [certified.validate(k) for k in t],
            ],
            repeats,
        )
        rows.append((label, len(trajs), total, t_naive, t_plain, t_numpy, t_cert))
    motions = workload_motions(model, seed, n_traj * 3)
    samples = [interpolate(k, model, Resolution()) for k, *_ in motions]
    t_naive, t_plain, t_numpy, t_cert = timed(
        [
            lambda: [m[3].validate(x) for m, x in zip(motions, samples, strict=True)],  # naive
            lambda: [p.validate(k) for k, _, p, _, _ in motions],
            lambda: [n.validate(k) for k, _, _, _, n in motions],
            lambda: [c.validate(k) for k, c, _, _, _ in motions],
        ],
        repeats,
    )
    total = sum(len(x) for x in samples)
    rows.append(("workload", len(motions), total, t_naive, t_plain, t_numpy, t_cert))
    return rows


def print_table(rows: list[Row]) -> dict[str, float]:
    """Print a line per row; states/s per checker and certified ms per trajectory, by label."""
    figures: dict[str, float] = {}
    print(
        f"{'trajectories':<16}{'count':>6}{'states':>8}{'naive st/s':>12}{'plain st/s':>12}"
        f"{'numpy st/s':>12}{'certified st/s':>16}{'ratio':>8}{'numpy ms':>10}"
        f"{'certified ms':>14}"
    )
    for label, count, total, t_naive, t_plain, t_numpy, t_cert in rows:
        figures[label] = a = total / t_naive
        figures[label + "/plain"] = total / t_plain
        figures[label + "/numpy"] = total / t_numpy
        figures[label + "/certified"] = c = total / t_cert
        figures[label + "/ms"] = t_cert / count * 1e3
        figures[label + "/numpy_ms"] = t_numpy / count * 1e3
        print(
            f"{label:<16}{count:>6}{total:>8}{a:>12.0f}{figures[label + '/plain']:>12.0f}"
            f"{figures[label + '/numpy']:>12.0f}{c:>16.0f}{c / a:>8.2f}"
            f"{figures[label + '/numpy_ms']:>10.2f}{figures[label + '/ms']:>14.2f}"
        )
    return figures


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table and the JSON line; 1 on a Panda safety mismatch."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--smoke", action="store_true", help="tiny run for CI")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--panda-problems", type=int, help="per family (default 10; smoke 1)")
    args = parser.parse_args(argv)
    n_traj, n_states, repeats = (4, 1000, 1) if args.smoke else (30, 10_000, 3)
    per_family = args.panda_problems or (1 if args.smoke else 10)

    warm()  # as the service does at startup: no timed call loads a compiled kernel
    rng = np.random.default_rng(args.seed)
    model = reference_model()
    scene = restroom_scene(doors=[30.0, 60.0, 90.0])
    checker = CollisionChecker(model, scene)
    naive = NaiveChecker(model, scene)
    rows = reference_rows(model, scene, checker, naive, rng, args.seed, n_traj, repeats)

    states = random_states(model, rng, n_states)
    began = time.perf_counter()
    naive_verdict = np.array([naive.state_collides(s) for s in states])
    t_naive_states = time.perf_counter() - began
    began = time.perf_counter()
    ours = checker.check(states, stop_at_first=False).status == COLLIDING
    t_ours_states = time.perf_counter() - began
    mismatches = int(np.sum(naive_verdict != ours))

    tally = validation_panda.run_panda(per_family, args.seed, repeats)
    panda = validation_panda.figures(tally)
    figures = print_table(rows + validation_panda.rows(tally))
    print(
        f"random states: {n_states}, colliding {int(ours.sum())}, mismatches {mismatches}; "
        f"per-state batch check {n_states / t_ours_states:.0f} st/s vs naive "
        f"{n_states / t_naive_states:.0f} st/s"
    )
    validation_panda.print_summary(panda)
    result = {
        "naive_states_per_s": round(figures["collision-free"], 1),
        "validator_states_per_s": round(figures["collision-free/certified"], 1),
        "validator_plain_states_per_s": round(figures["collision-free/plain"], 1),
        "ratio": round(figures["collision-free/certified"] / figures["collision-free"], 2),
        "ratio_plain": round(figures["collision-free/plain"] / figures["collision-free"], 2),
        "ratio_late": round(figures["collides late/certified"] / figures["collides late"], 2),
        "ratio_workload": round(figures["workload/certified"] / figures["workload"], 2),
        "ratio_numpy": round(figures["collision-free/numpy"] / figures["collision-free"], 2),
        "compiled_speedup": round(
            figures["collision-free/certified"] / figures["collision-free/numpy"], 2
        ),
        "validator_ms_per_trajectory": round(figures["collision-free/ms"], 3),
        "workload_ms_per_trajectory": round(figures["workload/ms"], 3),
        "mismatches": mismatches + panda["panda_mismatches"],
        "verdict_states": n_states,
        **panda,
        "smoke": args.smoke,
    }
    print(json.dumps(result))
    return 1 if panda["panda_mismatches"] else 0


if __name__ == "__main__":
    sys.exit(main())
