"""The reference scene: a public restroom with three toilet stalls, a sink counter and a dryer.

World frame: the floor is z = 0 (not an object: the robot stands on it), the room's interior
spans x ∈ [0, 6], y ∈ [0, 4]. The stalls line the north wall (y = 4) from the west wall; their
fronts are at y = 2.5 and each door is hinged on the stall's west side, swinging outward (−y)
into the room: 0° closed, 90° fully open. Seats are hinged at the back: 0° down, 90° up. Base
stations face each stall 1.2 m in front of its door (clear of the whole door sweep, not just of
the open door) and the sink 0.45 m in front of the counter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trajcache.geometry.errors import SceneError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene

ROOM_SIZE = (6.0, 4.0)
WALL_HEIGHT = 2.5
WALL_THICKNESS = 0.10
STALL_COUNT = 3
STALL_WIDTH = 0.90
STALL_DEPTH = 1.50
STALL_FRONT_Y = ROOM_SIZE[1] - STALL_DEPTH
PARTITION_THICKNESS = 0.025
PARTITION_BOTTOM = 0.15
PARTITION_HEIGHT = 1.80
DOOR_WIDTH = 0.80
DOOR_THICKNESS = 0.03
HINGE_OFFSET = 0.075  # hinge x from the stall's west edge
STATION_DISTANCE = 1.20  # stall station: base centre in front of the closed door's centre
COUNTER_X = (3.6, 5.2)
COUNTER_DEPTH = 0.55
COUNTER_HEIGHT = 0.85
BASIN_XS = (4.0, 4.8)
SINK_STATION_GAP = 0.45  # sink station: base centre this far in front of the counter
_BOWL_Y = 3.55
_SEAT_HINGE_Y = 3.76
_BASIN_Y = 0.30
_BASIN_HEIGHT = 0.14
_DRYER_CENTRE = (ROOM_SIZE[0] - 0.08, 1.0, 1.25)


@dataclass(frozen=True)
class StallFront:
    """Where stall `index` (1-based) is entered: door centre, hinge and the way into the stall."""

    index: int
    door_centre: tuple[float, float]
    facing: tuple[float, float]  # unit xy vector pointing into the stall
    hinge: tuple[float, float]
    toilet: tuple[float, float]  # bowl centre


@dataclass(frozen=True)
class BaseStation:
    """A base pose (x, y, θ) where the robot stops to work; θ faces the work area."""

    name: str
    x: float
    y: float
    theta: float

    @property
    def pose(self) -> tuple[float, float, float]:
        """The base state (x, y, θ)."""
        return (self.x, self.y, self.theta)


@dataclass(frozen=True)
class RestroomLayout:
    """Layout constants a workload generator needs (world frame, metres)."""

    room_min: tuple[float, float]
    room_max: tuple[float, float]
    wall_height: float
    stall_fronts: tuple[StallFront, ...]
    sink: tuple[float, float, float]  # counter top centre
    basins: tuple[tuple[float, float, float], ...]  # basin rim centres
    hand_dryer: tuple[float, float, float]
    stations: tuple[BaseStation, ...]

    def station(self, name: str) -> BaseStation:
        """The station called `name` ("stall_1" … "stall_3", "sink")."""
        for s in self.stations:
            if s.name == name:
                return s
        raise KeyError(name)


def _stall_x0(i: int) -> float:
    return (i - 1) * STALL_WIDTH


def restroom_layout() -> RestroomLayout:
    """The restroom's layout constants."""
    fronts = []
    for i in range(1, STALL_COUNT + 1):
        x0 = _stall_x0(i)
        hinge_x = x0 + HINGE_OFFSET
        fronts.append(
            StallFront(
                index=i,
                door_centre=(round(hinge_x + DOOR_WIDTH / 2, 9), STALL_FRONT_Y),
                facing=(0.0, 1.0),
                hinge=(round(hinge_x, 9), STALL_FRONT_Y),
                toilet=(round(x0 + STALL_WIDTH / 2, 9), _BOWL_Y),
            )
        )
    stations = [
        BaseStation(
            f"stall_{f.index}", f.door_centre[0], STALL_FRONT_Y - STATION_DISTANCE, math.pi / 2
        )
        for f in fronts
    ]
    sink_x = sum(COUNTER_X) / 2
    stations.append(BaseStation("sink", sink_x, COUNTER_DEPTH + SINK_STATION_GAP, -math.pi / 2))
    return RestroomLayout(
        room_min=(0.0, 0.0),
        room_max=ROOM_SIZE,
        wall_height=WALL_HEIGHT,
        stall_fronts=tuple(fronts),
        sink=(sink_x, COUNTER_DEPTH / 2, COUNTER_HEIGHT),
        basins=tuple((x, _BASIN_Y, COUNTER_HEIGHT + _BASIN_HEIGHT) for x in BASIN_XS),
        hand_dryer=_DRYER_CENTRE,
        stations=tuple(stations),
    )


def _pose(xyz: Sequence[float] | FloatArray, yaw: float = 0.0, roll: float = 0.0) -> FloatArray:
    """Translation times Rz(yaw) · Rx(roll)."""
    cz, sz, cx, sx = math.cos(yaw), math.sin(yaw), math.cos(roll), math.sin(roll)
    t = np.eye(4)
    t[:3, :3] = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]]
    )
    t[:3, 3] = xyz
    return t


class _Builder:
    """Collects objects, each with its jitter group (the parts of one fixture move together)."""

    def __init__(self) -> None:
        self.items: list[tuple[str, SceneObject]] = []

    def box(self, oid: str, size: Sequence[float], pose: FloatArray, group: str = "") -> None:
        self.items.append((group or oid, SceneObject(oid, Shape(ShapeKind.BOX, tuple(size)), pose)))

    def cylinder(
        self, oid: str, radius: float, length: float, pose: FloatArray, group: str = ""
    ) -> None:
        shape = Shape(ShapeKind.CYLINDER, (radius, length))
        self.items.append((group or oid, SceneObject(oid, shape, pose)))


def _walls(b: _Builder) -> None:
    (w, d), t, h = ROOM_SIZE, WALL_THICKNESS, WALL_HEIGHT
    b.box("wall_north", (w + 2 * t, t, h), _pose((w / 2, d + t / 2, h / 2)))
    b.box("wall_south", (w + 2 * t, t, h), _pose((w / 2, -t / 2, h / 2)))
    b.box("wall_west", (t, d, h), _pose((-t / 2, d / 2, h / 2)))
    b.box("wall_east", (t, d, h), _pose((w + t / 2, d / 2, h / 2)))


def _stall(b: _Builder, i: int, door: float, seat: float) -> None:
    x0, y0, back = _stall_x0(i), STALL_FRONT_Y, ROOM_SIZE[1]
    xc, z_mid = x0 + STALL_WIDTH / 2, PARTITION_BOTTOM + PARTITION_HEIGHT / 2
    east = x0 + STALL_WIDTH
    b.box(
        f"stall_{i}_partition",  # the partition on the stall's east side
        (PARTITION_THICKNESS, STALL_DEPTH, PARTITION_HEIGHT),
        _pose((east, y0 + STALL_DEPTH / 2, z_mid)),
    )
    west = x0 + (PARTITION_THICKNESS / 2 if i > 1 else 0.0)
    pilaster_w = x0 + HINGE_OFFSET - 0.005 - west
    b.box(
        f"stall_{i}_pilaster",
        (pilaster_w, DOOR_THICKNESS, PARTITION_HEIGHT),
        _pose((west + pilaster_w / 2, y0, z_mid)),
    )
    hinge = np.array([x0 + HINGE_OFFSET, y0, 0.0])
    yaw = -door  # opening turns the door's free end toward −y (out of the stall)
    door_frame = _pose(hinge, yaw)
    b.box(
        f"stall_{i}_door",
        (DOOR_WIDTH, DOOR_THICKNESS, PARTITION_HEIGHT),
        door_frame @ _pose((DOOR_WIDTH / 2, 0.0, z_mid)),
        group=f"stall_{i}_door",
    )
    b.box(
        f"stall_{i}_door_handle",  # on the outer face, near the free edge
        (0.03, 0.04, 0.12),
        door_frame @ _pose((DOOR_WIDTH - 0.08, -(DOOR_THICKNESS / 2 + 0.02), 1.0)),
        group=f"stall_{i}_door",
    )
    toilet = f"toilet_{i}"
    b.cylinder(f"{toilet}_bowl", 0.20, 0.40, _pose((xc, _BOWL_Y, 0.20)), toilet)
    b.box(f"{toilet}_base", (0.26, 0.27, 0.40), _pose((xc, 3.685, 0.20)), toilet)
    b.box(f"{toilet}_tank", (0.45, 0.18, 0.38), _pose((xc, back - 0.09, 0.60)), toilet)
    seat_frame = _pose((xc, _SEAT_HINGE_Y, 0.40), roll=-seat)  # lifting turns it toward +z
    b.box(f"{toilet}_seat", (0.38, 0.44, 0.03), seat_frame @ _pose((0.0, -0.22, 0.015)), toilet)
    b.box(f"stall_{i}_paper_holder", (0.12, 0.14, 0.12), _pose((east - 0.07, 3.30, 0.70)))
    b.cylinder(
        f"stall_{i}_grab_bar", 0.02, 0.60, _pose((west + 0.06, 3.40, 0.85), roll=math.pi / 2)
    )
    b.box(f"stall_{i}_bin", (0.15, 0.30, 0.30), _pose((x0 + 0.13, back - 0.17, 0.15)))


def _headrail(b: _Builder) -> None:
    row, top = STALL_COUNT * STALL_WIDTH, PARTITION_BOTTOM + PARTITION_HEIGHT
    b.box("stall_headrail", (row, 0.04, 0.04), _pose((row / 2, STALL_FRONT_Y, top + 0.02)))


def _sink_area(b: _Builder) -> None:
    x_mid, x_len = sum(COUNTER_X) / 2, COUNTER_X[1] - COUNTER_X[0]
    b.box(
        "sink_counter",
        (x_len, COUNTER_DEPTH, COUNTER_HEIGHT),
        _pose((x_mid, COUNTER_DEPTH / 2, COUNTER_HEIGHT / 2)),
        group="sink",
    )
    for n, x in enumerate(BASIN_XS, start=1):
        b.cylinder(
            f"sink_{n}_basin",
            0.19,
            _BASIN_HEIGHT,
            _pose((x, _BASIN_Y, COUNTER_HEIGHT + _BASIN_HEIGHT / 2)),
            "sink",
        )
        b.cylinder(f"sink_{n}_faucet", 0.02, 0.25, _pose((x, 0.07, COUNTER_HEIGHT + 0.125)), "sink")
        b.box(
            f"sink_{n}_soap",
            (0.07, 0.07, 0.18),
            _pose((x + 0.27, 0.12, COUNTER_HEIGHT + 0.09)),
            "sink",
        )
    b.box("mirror", (x_len - 0.2, 0.01, 0.90), _pose((x_mid, 0.005, 1.65)))
    b.box("hand_dryer", (0.16, 0.28, 0.28), _pose(_DRYER_CENTRE))
    b.cylinder("trash_bin", 0.20, 0.65, _pose((5.6, 0.45, 0.325)))


def _angles(values: Sequence[float] | float, what: str) -> list[float]:
    raw = [float(v) for v in np.atleast_1d(np.asarray(values, dtype=float))]
    if len(raw) == 1:
        raw = raw * STALL_COUNT
    if len(raw) != STALL_COUNT:
        raise SceneError(f"{what}: give one angle or {STALL_COUNT}, got {len(raw)}")
    for v in raw:
        if not (math.isfinite(v) and 0.0 <= v <= 90.0):
            raise SceneError(f"{what}: angles must be within 0..90 degrees, got {v}")
    return [math.radians(v) for v in raw]


def restroom_scene(
    doors: Sequence[float] | float = 0.0,
    seats: Sequence[float] | float = 0.0,
    offsets: FloatArray | None = None,
    seed: int | None = None,
    jitter_m: float = 0.0,
) -> Scene:
    """The restroom with door and seat angles in degrees (one for all stalls, or one per stall).

    `offsets` translates the scene: shape (3,) moves everything, (N, 3) moves each object (in
    scene order). `jitter_m` > 0 shifts each fixture (a door with its handle, a toilet, the sink)
    horizontally by a random vector of length in [jitter_m / 3, jitter_m], drawn from `seed`.
    """
    door_rad, seat_rad = _angles(doors, "doors"), _angles(seats, "seats")
    b = _Builder()
    _walls(b)
    for i in range(1, STALL_COUNT + 1):
        _stall(b, i, door_rad[i - 1], seat_rad[i - 1])
    _headrail(b)
    _sink_area(b)
    shifts = np.zeros((len(b.items), 3))
    if jitter_m > 0.0:
        rng = np.random.default_rng(seed)
        groups: dict[str, np.ndarray] = {}
        for k, (group, _) in enumerate(b.items):
            if group not in groups:
                angle, length = rng.uniform(0, 2 * math.pi), rng.uniform(jitter_m / 3, jitter_m)
                groups[group] = np.array([math.cos(angle), math.sin(angle), 0.0]) * length
            shifts[k] += groups[group]
    if offsets is not None:
        extra = np.asarray(offsets, dtype=float)
        if extra.shape not in ((3,), (len(b.items), 3)) or not np.all(np.isfinite(extra)):
            raise SceneError(f"offsets must be finite with shape (3,) or ({len(b.items)}, 3)")
        shifts += extra
    objects = []
    for (_, obj), shift in zip(b.items, shifts, strict=True):
        pose = obj.pose.copy()
        pose[:3, 3] += shift
        objects.append(SceneObject(obj.id, obj.shape, pose))
    env = {f"stall_{i + 1}_door": a for i, a in enumerate(door_rad)}
    env |= {f"stall_{i + 1}_seat": a for i, a in enumerate(seat_rad)}
    return make_scene(objects, env)


RESTROOM_LAYOUT = restroom_layout()
STALL_FRONTS = RESTROOM_LAYOUT.stall_fronts
STATIONS = RESTROOM_LAYOUT.stations
SINK_POSITION = RESTROOM_LAYOUT.sink
ROOM_BOUNDS = (RESTROOM_LAYOUT.room_min, RESTROOM_LAYOUT.room_max)
