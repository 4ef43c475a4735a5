"""Offline, seeded search for the cleaning workload's arm task configurations.

For every task a tool-tip target is given in the base frame (x forward, y left, z up; metres)
with an optional nozzle direction. Damped least-squares IK runs from hand-designed seeds and
random starts (seeded); every solution whose tip is within tolerance is scored by its clearance
to an *envelope* scene (the restroom with every stall door at 0°, 2°, … 90° and every seat at
0°, 45° and 90° all at once, so one check covers every door and seat angle) at every station of
its kind, by its self-clearance, and by how far it is from the stowed arm. The best one, rounded
to 3 decimals, is re-checked and printed as the constants for `trajcache/reference/tasks.py`.
`--verify` checks the constants in tasks.py instead: clearance, and a Monte-Carlo run of noisy
states (base ±3 cm, ±0.03 rad, joints ±0.03 rad) in jittered scenes.

    python bench/tools/find_tasks.py                 # search all kinds, print constants
    python bench/tools/find_tasks.py --kind sink     # one kind
    python bench/tools/find_tasks.py --verify        # check tasks.py as it is
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from typing import cast

import fcl
import numpy as np
from scipy.optimize import least_squares

from trajcache.geometry.collision.checker import FREE, CollisionChecker, robot_geometry
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.reference.restroom import STALL_COUNT, restroom_scene
from trajcache.reference.robot import ARM_MOUNT_XYZ, reference_model
from trajcache.reference.tasks import TASKS, Arm, WorkStation, work_stations

SCENE_MIN, SCENE_GOOD = 0.05, 0.10  # required / wanted clearance to the envelope (m)
SELF_MIN, SELF_GOOD = 0.03, 0.05  # the link5–link7 pair sits at 0.036 by construction
LIMIT_MARGIN = 0.08  # keep joints this far inside their limits (noise must not leave them)
CAP = 0.15  # distances beyond this are not resolved
STARTS = 150  # IK starts per task
NATURAL = [
    0,
    2,
    4,
    6,
]  # joints pulled towards the natural posture (1 towards the target, 3, 5, 7 at 0)


@dataclass(frozen=True)
class Target:
    """Tool tip at `tip` (base frame), nozzle along `direction` (None: any), from `seeds`."""

    tip: tuple[float, float, float]
    direction: tuple[float, float, float] | None = None
    seeds: tuple[tuple[float, ...], ...] = ()
    tolerance_m: float = 0.04
    tolerance_rad: float = 0.3


FWD_UP = (0.0, -0.6, 0.0, 1.2, 0.0, 0.6, 0.0)  # elbow up, wrist forward
FWD_LOW = (0.0, 0.2, 0.0, 1.2, 0.0, 1.0, 0.0)  # reaching forward and down
TARGETS: dict[str, dict[str, Target]] = {
    "stall": {
        # the door's free edge is to the front right; the arm stays outside the door sweep
        "reach_handle": Target((0.62, -0.30, 1.00), (1.0, 0.0, 0.0), (FWD_UP,)),
        "push_door": Target((0.70, -0.34, 0.90), (1.0, -0.2, 0.0), (FWD_UP,)),
        "lift_seat": Target((0.50, -0.18, 0.55), (1.0, 0.3, -0.6), (FWD_LOW,)),
        "lower_seat": Target((0.42, -0.05, 0.80), (1.0, 0.0, -0.3), (FWD_UP,)),
        "spray_bowl_left": Target((0.28, 0.15, 0.95), (1.0, -0.1, -0.35), (FWD_UP,)),
        "spray_bowl_right": Target((0.45, -0.20, 0.85), (1.0, 0.1, -0.35), (FWD_UP,)),
        "spray_rim": Target((0.40, 0.0, 1.15), (1.0, 0.0, -0.5), (FWD_UP,)),
        "spray_wall_left": Target((0.30, 0.30, 1.25), (0.8, 0.5, 0.2), (FWD_UP,)),
        "spray_wall_right": Target((0.55, -0.32, 1.30), (0.8, -0.3, 0.2), (FWD_UP,)),
        "spray_floor_a": Target((0.55, -0.25, 0.32), (1.0, 0.0, -1.0), (FWD_LOW,)),
        "spray_floor_b": Target((0.25, -0.45, 0.30), (0.3, -0.5, -1.0), (FWD_LOW,)),
        "dry_seat": Target((0.50, -0.20, 0.70), (1.0, 0.0, -0.8), (FWD_LOW, FWD_UP)),
        "dry_floor": Target((0.30, -0.42, 0.25), (0.3, -0.3, -1.0), (FWD_LOW,)),
    },
    "sink": {
        # counter front 0.45 m ahead (top 0.85 m), basins 0.4 m left and right, rims at 0.99 m
        "sink_spray_left": Target((0.50, 0.30, 1.12), (1.0, 0.3, -0.6), (FWD_UP,)),
        "sink_spray_right": Target((0.50, -0.30, 1.12), (1.0, -0.3, -0.6), (FWD_UP,)),
        "sink_wipe_a": Target((0.46, 0.28, 1.05), (1.0, 0.0, -1.0), (FWD_UP,)),
        "sink_wipe_b": Target((0.46, -0.28, 1.05), (1.0, 0.0, -1.0), (FWD_UP,)),
        "counter_wipe_a": Target((0.50, 0.08, 0.96), (1.0, 0.0, -1.0), (FWD_UP,)),
        "counter_wipe_b": Target((0.50, -0.10, 0.96), (1.0, 0.0, -1.0), (FWD_UP,)),
        "faucet_spray": Target((0.50, 0.0, 1.15), (1.0, 0.0, -0.4), (FWD_UP,)),
        "mirror_spray_a": Target((0.40, 0.20, 1.30), (1.0, 0.0, 0.3), (FWD_UP,)),
        "mirror_spray_b": Target((0.40, -0.20, 1.30), (1.0, 0.0, 0.3), (FWD_UP,)),
        "sink_dry_left": Target((0.45, 0.32, 1.05), (1.0, 0.4, -0.8), (FWD_UP,)),
        "sink_dry_right": Target((0.45, -0.32, 1.05), (1.0, -0.4, -0.8), (FWD_UP,)),
    },
    "dryer": {
        # the dryer's front face is 0.54 m ahead at 1.11…1.39 m; a bin is 0.35 m to the right
        "dryer_spray": Target((0.38, 0.0, 1.25), (1.0, 0.0, 0.0), (FWD_UP,)),
        "dryer_wipe_a": Target((0.44, 0.08, 1.32), (1.0, 0.0, 0.0), (FWD_UP,)),
        "dryer_wipe_b": Target((0.44, -0.08, 1.18), (1.0, 0.0, 0.0), (FWD_UP,)),
        "dryer_dry": Target((0.40, 0.0, 1.05), (1.0, 0.0, 0.3), (FWD_UP,)),
    },
}

MODEL = reference_model()
TIP = MODEL.link_names.index("tool_tip")
LOWER = np.maximum(MODEL.lower[3:], -math.pi) + LIMIT_MARGIN
UPPER = np.minimum(MODEL.upper[3:], math.pi) - LIMIT_MARGIN


def envelope_scene() -> Scene:
    """The restroom with every door angle 0…90° (2° steps) and seat 0/45/90° at once."""
    objects: dict[str, SceneObject] = {o.id: o for o in restroom_scene().objects}
    swept = ("_door", "_door_handle", "_seat")
    for angle in range(2, 91, 2):
        for obj in restroom_scene(doors=angle, seats=angle).objects:
            seat = obj.id.endswith("_seat")
            if obj.id.endswith(swept) and (not seat or angle in (46, 90)):
                objects[f"{obj.id}@{angle}"] = SceneObject(f"{obj.id}@{angle}", obj.shape, obj.pose)
    return make_scene(objects.values())


def tool_tip(arm: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Tool-tip position and nozzle direction (base frame) of arm configurations (N, 7)."""
    states = np.hstack([np.zeros((len(arm), 3)), arm])
    tf = link_transforms(MODEL, states)[:, TIP]
    return tf[:, :3, 3], tf[:, :3, 2]


def natural_arm(target: Target) -> FloatArray:
    """The planar arm posture towards the target: joint 1 turned to it, joints 3, 5, 7 at 0."""
    yaw = math.atan2(target.tip[1], target.tip[0] - ARM_MOUNT_XYZ[0])
    return np.array([yaw, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])


def solve_ik(target: Target, start: FloatArray) -> tuple[FloatArray, float, float]:
    """Damped least-squares IK from `start`; returns (arm, position error, direction error)."""
    goal = np.array(target.tip)
    axis = None if target.direction is None else np.array(target.direction)
    if axis is not None:
        axis = axis / np.linalg.norm(axis)
    prior = natural_arm(target)

    def residual(q: FloatArray) -> FloatArray:
        pos, direction = tool_tip(q[None])
        res = [pos[0] - goal]
        if axis is not None:
            res.append(0.3 * (direction[0] - axis))
        res.append(0.02 * (q - prior)[NATURAL])  # mild pull towards the natural posture
        return np.concatenate(res)

    sol = least_squares(residual, np.clip(start, LOWER, UPPER), bounds=(LOWER, UPPER))
    pos, direction = tool_tip(sol.x[None])
    angle = 0.0 if axis is None else float(np.arccos(np.clip(direction[0] @ axis, -1.0, 1.0)))
    return sol.x, float(np.linalg.norm(pos[0] - goal)), angle


def clearances(scene: Scene, states: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per state: distance to the scene and between non-adjacent links (capped at CAP)."""
    checker = CollisionChecker(MODEL, scene)
    rg, sg = robot_geometry(MODEL), checker.scene
    poses = checker.element_poses(states)
    centers = poses[:, :, :3, 3]
    rel = centers[:, :, None, :] - sg.position[None, None]
    local = np.einsum("mji,nemj->nemi", sg.rotation, rel)
    bound = np.linalg.norm(np.maximum(np.abs(local) - sg.half[None, None], 0.0), axis=-1)
    bound -= rg.radius[None, :, None]
    to_scene, to_self = np.full(len(states), CAP), np.full(len(states), CAP)
    objs, req = rg.objects(), fcl.DistanceRequest()
    for s in range(len(states)):
        for e, obj in enumerate(objs):
            obj.setTranslation(poses[s, e, :3, 3])
            obj.setRotation(poses[s, e, :3, :3])
        for e, b in np.argwhere(bound[s] < CAP):
            d = fcl.distance(objs[e], sg.objects[b], req, fcl.DistanceResult())
            to_scene[s] = min(to_scene[s], d)
        for i, j in zip(rg.pair_i, rg.pair_j, strict=True):
            d = fcl.distance(objs[i], objs[j], req, fcl.DistanceResult())
            to_self[s] = min(to_self[s], d)
    return to_scene, to_self


def station_clearance(
    scene: Scene, stations: list[WorkStation], arms: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Worst clearance of each arm configuration over `stations`."""
    states = np.vstack([np.hstack([np.tile(s.pose, (len(arms), 1)), arms]) for s in stations])
    to_scene, to_self = clearances(scene, states)
    return to_scene.reshape(len(stations), -1).min(0), to_self.reshape(len(stations), -1).min(0)


def search(
    kind: str, name: str, target: Target, scene: Scene, rng: np.random.Generator
) -> Arm | None:
    """The best IK solution for `target` at every station of `kind` (None: not found)."""
    stations = [s for s in work_stations() if s.kind == kind]
    prior = natural_arm(target)
    starts = [np.array(s, dtype=float) for s in target.seeds]
    for _ in range(STARTS):  # natural postures: joint 1 towards the target, elbow up
        start = prior + rng.normal(0.0, 0.25, 7) * [1, 0, 1, 0, 1, 0, 0]
        start[[1, 3, 5]] = rng.uniform([-1.2, 0.0, -1.2], [1.2, 2.8, 2.4])
        starts.append(start)
    found = []
    for start in starts:
        arm, pos_err, dir_err = solve_ik(target, start)
        if pos_err <= target.tolerance_m and dir_err <= target.tolerance_rad:
            found.append(np.round(arm, 3))
    if not found:
        print(f"# {kind}/{name}: NO IK SOLUTION within tolerance")
        return None
    arms = np.unique(np.array(found), axis=0)
    to_scene, to_self = station_clearance(scene, stations, arms)
    spread = np.max(np.abs(arms - prior)[:, NATURAL], axis=1)
    score = (
        np.minimum(to_scene, SCENE_GOOD) / SCENE_GOOD
        + 0.5 * np.minimum(to_self, SELF_GOOD) / SELF_GOOD
        - 0.1 * spread
    )
    score[(to_scene < SCENE_MIN) | (to_self < SELF_MIN)] -= 10.0
    best = int(np.argmax(score))
    print(
        f"# {kind}/{name}: {len(arms)} solutions, best scene {to_scene[best]:.3f} m, "
        f"self {to_self[best]:.3f} m"
    )
    if score[best] < 0:
        print(f"# {kind}/{name}: NO SOLUTION with enough clearance")
        return None
    return cast(Arm, tuple(float(v) for v in arms[best]))


def noisy_check(scene_seed: int, samples: int) -> int:
    """Monte-Carlo: noisy task states in jittered scenes; returns the number of collisions."""
    rng = np.random.default_rng(scene_seed)
    failures = 0
    for trial in range(4):
        doors = rng.uniform(0, 90, STALL_COUNT)
        seats = rng.choice([0.0, 90.0], STALL_COUNT)
        scene = restroom_scene(doors=doors, seats=seats, jitter_m=0.02, seed=scene_seed + trial)
        checker = CollisionChecker(MODEL, scene)
        for station in work_stations():
            for name, arm in TASKS[station.kind].items():
                base = np.array(station.pose) + rng.uniform(-1, 1, (samples, 3)) * 0.03
                arms = np.array(arm) + rng.uniform(-1, 1, (samples, 7)) * 0.03
                verdict = checker.check(np.hstack([base, arms]), stop_at_first=False)
                bad = int(np.sum(verdict.status != FREE))
                if bad:
                    print(f"  {station.name}/{name}: {bad}/{samples} noisy states collide")
                failures += bad
    return failures


def verify(scene: Scene) -> None:
    """Print the clearance of every configuration in tasks.py and the Monte-Carlo result."""
    for kind, tasks in TASKS.items():
        stations = [s for s in work_stations() if s.kind == kind]
        arms = np.array(list(tasks.values()))
        to_scene, to_self = station_clearance(scene, stations, arms)
        inside = np.all((arms >= LOWER - LIMIT_MARGIN / 2) & (arms <= UPPER + LIMIT_MARGIN / 2), 1)
        for name, a, b, ok in zip(tasks, to_scene, to_self, inside, strict=True):
            flag = "" if a >= SCENE_MIN and b >= SELF_MIN and ok else "   <-- TOO CLOSE"
            print(f"{kind:6s} {name:18s} scene {a:.3f} m  self {b:.3f} m{flag}")
    print(f"Monte-Carlo collisions: {noisy_check(7, 100)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", choices=sorted(TARGETS), action="append")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--verify", action="store_true")
    args = parser.parse_args()
    scene = envelope_scene()
    if args.verify:
        verify(scene)
        return
    rng = np.random.default_rng(args.seed)
    for kind in args.kind or sorted(TARGETS):
        print(f'{kind.upper()}_TASKS = {{\n    "stow": STOW,')
        lines = []
        for name, target in TARGETS[kind].items():
            arm = search(kind, name, target, scene, rng)
            if arm is None:
                continue
            values = ", ".join(f"{v if abs(v) >= 5e-4 else 0.0:.3f}" for v in arm)
            lines.append(f"    {name!r}: ({values}),")
        print("\n".join(lines).replace("'", '"') + "\n}")


if __name__ == "__main__":
    main()
