"""Named arm task configurations of the cleaning workload, their order, and the base stations.

Each task configuration is a 7-vector of arm joints, relative to the base, found offline by
`bench/tools/find_tasks.py` (seeded IK towards a tool-tip target, then chosen for clearance) and
hard-coded here. Every configuration keeps at least 5 cm to the restroom and 3 cm to the robot
itself at every station of its kind, for every door angle 0…90° and seat up or down, so that
execution noise keeps it free. Stall stations stand clear of the whole door sweep, so the arm works
from outside the stall: "reach_handle" and "push_door" reach towards the door's free edge, the
spray and dry poses aim the nozzle into the stall.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.model.shapes import FloatArray
from trajcache.reference.restroom import restroom_layout
from trajcache.reference.robot import STOWED_ARM

Arm = tuple[float, float, float, float, float, float, float]

STOW: Arm = STOWED_ARM
DRYER_STANDOFF = 0.62  # dryer station: base centre this far in front of the dryer's centre

# Found by bench/tools/find_tasks.py (seed 0); tool-tip targets are listed there.
STALL_TASKS: dict[str, Arm] = {
    "stow": STOW,
    "reach_handle": (0.736, -0.828, -0.968, 1.062, 0.341, 0.076, 0.000),
    "push_door": (1.161, -0.821, -1.352, 1.062, 0.214, -0.356, 0.000),
    "lift_seat": (0.452, -0.977, -1.393, 0.234, 0.368, 0.092, 0.000),
    "lower_seat": (-0.160, -1.823, -0.198, -0.005, 0.088, 0.562, 0.000),
    "spray_bowl_left": (0.491, -1.424, 0.487, 0.766, -0.391, 1.272, 0.000),
    "spray_bowl_right": (-0.158, -1.155, -0.559, 0.484, 0.431, 0.600, 0.000),
    "spray_rim": (0.000, -0.876, 0.000, 1.483, 0.000, 1.252, 0.000),
    "spray_wall_left": (0.464, -0.839, 0.337, 1.318, -0.438, 0.423, 0.000),
    "spray_wall_right": (-0.525, -0.138, -0.165, 1.929, 0.895, 0.413, 0.000),
    "spray_floor_a": (-0.654, 0.652, -0.054, 0.855, 2.225, 0.666, 0.000),
    "spray_floor_b": (-1.604, 0.833, 0.086, 0.688, -0.323, -0.634, 0.000),
    "dry_seat": (-0.170, -0.805, -0.472, 0.355, 0.424, 0.373, 0.000),
    "dry_floor": (-2.080, 1.072, 0.549, 1.078, -2.152, 0.181, 0.000),
}
SINK_TASKS: dict[str, Arm] = {
    "stow": STOW,
    "sink_spray_left": (0.619, -0.330, 0.217, 1.728, -0.459, 1.138, 0.000),
    "sink_spray_right": (-0.619, -0.330, -0.217, 1.728, 0.459, 1.138, 0.000),
    "sink_wipe_a": (0.718, -0.280, 0.274, 1.782, -0.559, 1.569, 0.000),
    "sink_wipe_b": (-0.718, -0.280, -0.274, 1.782, 0.559, 1.569, 0.000),
    "counter_wipe_a": (0.167, -0.793, 0.097, 1.075, -0.129, 1.104, 0.000),
    "counter_wipe_b": (-0.209, -0.771, -0.119, 1.090, 0.162, 1.110, 0.000),
    "faucet_spray": (0.000, -0.723, 0.000, 1.416, 0.000, 0.949, 0.000),
    "mirror_spray_a": (-0.085, -0.784, 0.387, 1.503, -0.543, 0.505, 0.000),
    "mirror_spray_b": (0.085, -0.784, -0.387, 1.503, 0.543, 0.505, 0.000),
    "sink_dry_left": (0.713, -0.461, 0.209, 1.483, -0.385, 1.131, 0.000),
    "sink_dry_right": (-0.713, -0.461, -0.209, 1.483, 0.385, 1.131, 0.000),
}
DRYER_TASKS: dict[str, Arm] = {
    "stow": STOW,
    "dryer_spray": (0.000, -0.953, 0.000, 1.390, 0.000, 0.772, 0.000),
    "dryer_wipe_a": (0.054, -0.584, 0.161, 1.837, -0.243, 0.875, 0.000),
    "dryer_wipe_b": (-0.015, -0.978, -0.146, 1.109, 0.187, 0.530, 0.000),
    "dryer_dry": (0.000, -1.436, 0.000, 0.347, 0.000, -0.080, 0.000),
}
TASKS: dict[str, dict[str, Arm]] = {"stall": STALL_TASKS, "sink": SINK_TASKS, "dryer": DRYER_TASKS}


# The fixed order of tasks at each station kind: every task is one arm move from the previous one
# (the arm arrives stowed). Markers are scene events: the door opens, the seat goes up or down.
OPEN_DOOR, SEAT_UP, SEAT_DOWN = "@open_door", "@seat_up", "@seat_down"


def _passes(pair: tuple[str, str], count: int) -> list[str]:
    """`count` back-and-forth passes: a, b, a, b, …"""
    return [pair[i % 2] for i in range(2 * count)]


_BOWL, _WALLS = ("spray_bowl_left", "spray_bowl_right"), ("spray_wall_left", "spray_wall_right")
_FLOOR = ("spray_floor_a", "spray_floor_b")
STALL_ROUTE: tuple[str, ...] = (
    *("reach_handle", "push_door", OPEN_DOOR, "stow", "lift_seat", SEAT_UP, "stow"),
    *_passes(_BOWL, 4), "spray_rim", *_passes(_WALLS, 2), *_passes(_FLOOR, 2), "stow",  # chemical
    *_passes(_BOWL, 4), "spray_rim", *_passes(_WALLS, 1), *_passes(_FLOOR, 2), "stow",  # scrub
    *_passes(_BOWL, 3), "spray_rim", *_passes(_WALLS, 2), *_passes(_FLOOR, 2), "stow",  # rinse
    *_passes(("dry_seat", "dry_floor"), 4), "stow",  # dry
    *("lower_seat", SEAT_DOWN, "stow"),
)  # fmt: skip
_BASINS = ("sink_spray_left", "sink_spray_right")
SINK_ROUTE: tuple[str, ...] = (
    *_passes(_BASINS, 4), "faucet_spray", *_passes(("mirror_spray_a", "mirror_spray_b"), 2),
    "stow",  # chemical
    *_passes(("sink_wipe_a", "sink_wipe_b"), 3), *_passes(("counter_wipe_a", "counter_wipe_b"), 3),
    "stow",  # scrub
    *_passes(_BASINS, 4), "faucet_spray", "stow",  # rinse
    *_passes(("sink_dry_left", "sink_dry_right"), 3),
    *_passes(("counter_wipe_a", "counter_wipe_b"), 3),
    *_passes(("mirror_spray_a", "mirror_spray_b"), 2), "stow",  # dry
)  # fmt: skip
DRYER_ROUTE: tuple[str, ...] = (
    "dryer_spray", *_passes(("dryer_wipe_a", "dryer_wipe_b"), 3), "dryer_dry", "stow",
)  # fmt: skip
ROUTES = {"stall": STALL_ROUTE, "sink": SINK_ROUTE, "dryer": DRYER_ROUTE}


@dataclass(frozen=True)
class WorkStation:
    """A base pose where the arm works; `kind` selects the task configurations used there."""

    name: str  # "stall_1" … "stall_3", "sink", "dryer"
    kind: str  # "stall" | "sink" | "dryer"
    pose: tuple[float, float, float]  # base x, y, θ


@functools.lru_cache(maxsize=1)
def work_stations() -> tuple[WorkStation, ...]:
    """The stations of a cleaning run in visiting order: the stalls, the sink, the dryer."""
    layout = restroom_layout()
    stations = [
        WorkStation(s.name, "stall" if s.name.startswith("stall") else "sink", (s.x, s.y, s.theta))
        for s in layout.stations
    ]
    dx, dy, _ = layout.hand_dryer
    # The dryer hangs on the east wall: face it from the west.
    stations.append(WorkStation("dryer", "dryer", (round(dx - DRYER_STANDOFF, 9), dy, 0.0)))
    return tuple(stations)


def work_station(name: str) -> WorkStation:
    """The station called `name`."""
    for station in work_stations():
        if station.name == name:
            return station
    raise KeyError(name)


def task_arm(kind: str, task: str) -> FloatArray:
    """The arm joints (7,) of `task` at a station of `kind`."""
    try:
        return np.array(TASKS[kind][task], dtype=float)
    except KeyError:
        raise KeyError(f"no task {task!r} at a {kind!r} station") from None


def task_state(station: WorkStation, task: str, base: FloatArray | None = None) -> FloatArray:
    """The full state (10,) of `task` at `station`, at `base` (x, y, θ) when given."""
    pose = np.asarray(station.pose if base is None else base, dtype=float)
    return np.concatenate([pose, task_arm(station.kind, task)])
