"""A deterministic generator of one cleaning run: the planning calls, like the paper's ~270.

The base drives from the entrance to a station in front of each stall, then the sink and the hand
dryer, and back (arm stowed while driving, an aisle waypoint between stations). At each station
the arm moves between task configurations in a fixed order: open the door, lift the seat, spray
chemical, scrub, rinse, dry, lower the seat. The order never changes; the seed only draws the
execution noise and the door angles, so run 2 resembles run 1 (that is what makes caching work).

Execution noise: each call starts where the previous call actually ended, which is its nominal
goal plus Gaussian noise (σ = bound / 2, clipped to the bound). Arm moves keep the base where it
actually is (start base == goal base exactly); base moves aim for the nominal waypoint.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from trajcache.cache.metric import wrap_angle
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.restroom import STALL_COUNT, restroom_scene
from trajcache.reference.robot import ARM_JOINTS
from trajcache.reference.tasks import (
    OPEN_DOOR,
    ROUTES,
    SEAT_DOWN,
    SEAT_UP,
    STOW,
    task_arm,
    work_station,
    work_stations,
)

Angles = tuple[float, ...]  # one angle per stall (degrees)
START_POSE = (4.8, 2.6, math.pi)  # the entrance, east of the stalls; the run ends there too
REAL_ROOM_SEED = 2025  # object jitter of the "real robot" restroom (the same room every run)


@dataclass(frozen=True)
class Noise:
    """Bounds of the execution noise; each value is Gaussian (σ = bound / 2) clipped to ±bound."""

    base_xy_m: float = 0.02
    base_theta_rad: float = 0.02
    joint_rad: float = 0.02

    def sample(self, rng: np.random.Generator, size: int, bound: float) -> FloatArray:
        """`size` noise values within ±`bound`."""
        return np.clip(rng.normal(0.0, bound / 2.0, size), -bound, bound)


PERTURBED_NOISE = Noise(base_xy_m=0.03, base_theta_rad=0.03, joint_rad=0.03)


@dataclass(frozen=True, eq=False)
class PlanCall:
    """One planning request of the run, with the scene in force when it is made."""

    index: int
    label: str  # e.g. "stall 2: spray_bowl_left → spray_bowl_right", "drive: sink → dryer"
    start: FloatArray  # (10,) where the robot actually is
    goal: FloatArray  # (10,) nominal target (arm moves: at the actual base pose)
    doors_deg: Angles
    seats_deg: Angles
    base_moves: bool
    station: str  # the station of an arm move, the destination of a base move


@dataclass(frozen=True)
class SceneEvent:
    """The scene changes before call `before_call` (a door opened, a seat lifted or lowered)."""

    before_call: int
    label: str
    doors_deg: Angles
    seats_deg: Angles


@dataclass
class CleaningRun:
    """The calls of one run; scenes come from `scene_for` (jittered for a perturbed run)."""

    seed: int
    calls: list[PlanCall]
    events: list[SceneEvent]
    perturbed: bool = False
    jitter_m: float = 0.0
    jitter_seed: int | None = None
    noise: Noise = field(default_factory=Noise)

    def scene(self, doors_deg: Sequence[float], seats_deg: Sequence[float]) -> Scene:
        """The restroom of this run with the given door and seat angles (cached)."""
        return _scene(tuple(doors_deg), tuple(seats_deg), self.jitter_m, self.jitter_seed)

    def scene_for(self, call: PlanCall) -> Scene:
        """The scene in force when `call` is made."""
        return self.scene(call.doors_deg, call.seats_deg)


@functools.lru_cache(maxsize=256)
def _scene(doors: Angles, seats: Angles, jitter_m: float, jitter_seed: int | None) -> Scene:
    return restroom_scene(doors=doors, seats=seats, jitter_m=jitter_m, seed=jitter_seed)


def _waypoints() -> dict[str, tuple[float, float, float]]:
    """Named base poses: the stations, the aisle between them and the entrance."""
    poses = {s.name: s.pose for s in work_stations()}
    names = [f"stall_{i}" for i in range(1, STALL_COUNT + 1)] + ["sink"]
    for a, b in itertools.pairwise(names):
        (xa, ya, _), (xb, yb, _) = poses[a], poses[b]
        # back off from the stalls; on the way to the sink pass north of the counter
        dy = -0.25 if b.startswith("stall") else 0.25
        poses[f"aisle_{a}_{b}"] = (round((xa + xb) / 2, 9), round((ya + yb) / 2 + dy, 9), 0.0)
    first = poses["stall_1"]
    poses["aisle"] = (round(poses[f"stall_{STALL_COUNT}"][0] + 0.6, 9), first[1], math.pi)
    poses["entrance"] = START_POSE
    return poses


def _drive_route() -> list[str]:
    """Waypoints visited in order, stations included."""
    names = [f"stall_{i}" for i in range(1, STALL_COUNT + 1)] + ["sink"]
    route = ["entrance", "aisle", names[0]]
    for a, b in itertools.pairwise(names):
        route += [f"aisle_{a}_{b}", b]
    return [*route, "dryer", "entrance"]


def _arm_limits() -> tuple[FloatArray, FloatArray]:
    lower = np.array([max(j.lower, -math.pi) for j in ARM_JOINTS])
    upper = np.array([min(j.upper, math.pi) for j in ARM_JOINTS])
    return lower, upper


def _between_tens(rng: np.random.Generator, low: float, high: float) -> float:
    """Uniform over the parts of [low, high] at least 2° from every multiple of 10°."""
    parts = [(max(low, c - 3.0), min(high, c + 3.0)) for c in range(5, 91, 10)]
    parts = [(a, b) for a, b in parts if b > a]
    if not parts:  # the range allows no such angle
        return float(rng.uniform(low, high))
    lengths = np.array([b - a for a, b in parts])
    a, b = parts[int(rng.choice(len(parts), p=lengths / lengths.sum()))]
    return float(rng.uniform(a, b))


def _angle(rng: np.random.Generator, low: float, high: float, perturbed: bool) -> float:
    value = _between_tens(rng, low, high) if perturbed else rng.uniform(low, high)
    return round(float(value), 1)


class _Walker:
    """Walks the fixed route, drawing noise and recording calls and scene changes."""

    def __init__(self, rng: np.random.Generator, noise: Noise) -> None:
        self.rng, self.noise = rng, noise
        self.lower, self.upper = _arm_limits()
        self.calls: list[PlanCall] = []
        self.events: list[SceneEvent] = []
        self.doors: list[float] = [0.0] * STALL_COUNT
        self.seats: list[float] = [0.0] * STALL_COUNT
        self.state = self.reach(np.array([*START_POSE, *STOW]), base_moved=True)

    def reach(self, goal: FloatArray, *, base_moved: bool) -> FloatArray:
        """Where the robot actually ends up when it aims for `goal`."""
        n = self.noise
        state = goal.copy()
        if base_moved:
            state[:2] += n.sample(self.rng, 2, n.base_xy_m)
            state[2] = wrap_angle(state[2] + n.sample(self.rng, 1, n.base_theta_rad)[0])
        state[3:] = np.clip(state[3:] + n.sample(self.rng, 7, n.joint_rad), self.lower, self.upper)
        return state

    def move(self, label: str, goal: FloatArray, station: str, *, base_moves: bool) -> None:
        self.calls.append(
            PlanCall(
                index=len(self.calls),
                label=label,
                start=self.state,
                goal=goal,
                doors_deg=tuple(self.doors),
                seats_deg=tuple(self.seats),
                base_moves=base_moves,
                station=station,
            )
        )
        self.state = self.reach(goal, base_moved=base_moves)

    def change(self, label: str, doors: list[float], seats: list[float]) -> None:
        if doors == self.doors and seats == self.seats:
            return
        self.doors, self.seats = list(doors), list(seats)
        self.events.append(SceneEvent(len(self.calls), label, tuple(doors), tuple(seats)))


def _generate(
    stream: list[int],
    noise: Noise,
    initial: Sequence[float],
    opened: Sequence[float],
    seat_up: float,
) -> tuple[list[PlanCall], list[SceneEvent]]:
    """The calls and scene events of a run with the given door angles (per stall)."""
    walker = _Walker(np.random.default_rng(stream), noise)
    walker.doors = [float(a) for a in initial]
    poses = _waypoints()
    route = _drive_route()
    for here, there in itertools.pairwise(route):
        goal = np.array([*poses[there], *STOW])
        walker.move(f"drive: {here} → {there}", goal, there, base_moves=True)
        if there not in {s.name for s in work_stations()}:
            continue
        station = work_station(there)
        k = int(there.rsplit("_", 1)[1]) - 1 if station.kind == "stall" else -1
        task = "stow"
        for step in ROUTES[station.kind]:
            doors, seats = list(walker.doors), list(walker.seats)
            if step == OPEN_DOOR:
                doors[k] = float(opened[k])
                walker.change(f"{there} door opened to {doors[k]:g}°", doors, seats)
                continue
            if step in (SEAT_UP, SEAT_DOWN):
                seats[k] = seat_up if step == SEAT_UP else 0.0
                walker.change(f"{there} seat at {seats[k]:g}°", doors, seats)
                continue
            goal = np.concatenate([walker.state[:3], task_arm(station.kind, step)])
            label = f"{there.replace('_', ' ')}: {task} → {step}"
            walker.move(label, goal, there, base_moves=False)
            task = step
    return walker.calls, walker.events


def cleaning_run(
    seed: int,
    *,
    noise: Noise | None = None,
    door_open_deg: tuple[float, float] = (75.0, 90.0),
    initial_doors_deg: Sequence[float] | None = None,
    perturbed: bool = False,
    jitter_m: float = 0.02,
    jitter_seed: int = REAL_ROOM_SEED,
) -> CleaningRun:
    """One cleaning run; the seed draws the noise and the door angles, never the call order.

    Doors start at `initial_doors_deg` (default: per stall, random in 0…20°) and the robot opens
    each to a random angle in `door_open_deg`. `perturbed` is the "real robot": larger noise
    (`PERTURBED_NOISE` unless `noise` is given), door angles between the multiples of 10° that
    pre-seeding uses, seats lifted to 82…88° and the restroom's fixtures shifted by up to
    `jitter_m` (the same shift every run: `jitter_seed`).
    """
    rng = np.random.default_rng([seed, 0, int(perturbed)])
    if initial_doors_deg is None:
        initial = [_angle(rng, 0.0, 20.0, perturbed) for _ in range(STALL_COUNT)]
    else:
        initial = [float(a) for a in initial_doors_deg]
    opened = [_angle(rng, *door_open_deg, perturbed) for _ in range(STALL_COUNT)]
    seat_up = _angle(rng, 82.0, 88.0, False) if perturbed else 90.0
    noise = noise or (PERTURBED_NOISE if perturbed else Noise())
    calls, events = _generate([seed, 1, int(perturbed)], noise, initial, opened, seat_up)
    return CleaningRun(
        seed=seed,
        calls=calls,
        events=events,
        perturbed=perturbed,
        jitter_m=jitter_m if perturbed else 0.0,
        jitter_seed=jitter_seed if perturbed else None,
        noise=noise,
    )


def door_sweep_run(door_deg: float, seed: int, *, noise: Noise | None = None) -> CleaningRun:
    """A pre-seeding run with every door at `door_deg` for the whole run (push_door kept)."""
    angles = [float(door_deg)] * STALL_COUNT
    noise = noise or Noise()
    stream = [seed, 2, round(door_deg * 10)]  # noise unlike any other run's
    calls, events = _generate(stream, noise, angles, angles, 90.0)
    return CleaningRun(seed=seed, calls=calls, events=events, noise=noise)
