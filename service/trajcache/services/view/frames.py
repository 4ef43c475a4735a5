"""Link world poses along a path, one frame per validation sample, for the 3D view.

A frame is a state of the path's dense validation samples (`geometry.validation.validator
.interpolate`, at the service's step sizes): frame k of a path with no more than `MAX_FRAMES`
samples is validation sample k, so the sample a rejection names is a frame of its path. A
longer path is thinned evenly, each frame keeping the index of its sample. Key states are
always frames.

Only the links that draw something are posed: those with collision geometry, the end
effector (its origin traces the swept path) and links the scene attaches objects to.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trajcache.core.config import Settings
from trajcache.geometry.model.poses import link_poses
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray
from trajcache.geometry.path_quality import end_effector_link
from trajcache.geometry.validation.sampling import Resolution, interpolate, sample_counts

__all__ = ["MAX_FRAMES", "PathFrames", "path_frames", "posed_links", "resolution_of"]

MAX_FRAMES = 2000
DIGITS = 6  # poses to the micrometre


@dataclass(frozen=True)
class PathFrames:
    """The frames of a path: its states, where they are among the validation samples, and the
    world poses (x, y, z, qx, qy, qz, qw) of the posed links."""

    states: FloatArray  # (N, D)
    sample: NDArray[np.int64]  # (N,) validation sample of each frame
    samples: int  # validation samples of the whole path
    key: NDArray[np.int64]  # frame of each key state
    links: list[int]  # the posed links, in the order of each frame's poses
    poses: FloatArray  # (N, K, 7)


def resolution_of(settings: Settings) -> Resolution:
    """The validation step sizes of the service's settings."""
    return Resolution(
        settings.step_position_m, settings.step_orientation_rad, settings.step_joint_rad
    )


def posed_links(model: RobotModel, attached_to: Iterable[str] = ()) -> list[int]:
    """Links with collision geometry, the end effector and the links named in `attached_to`."""
    index = {name: i for i, name in enumerate(model.link_names)}
    wanted = {int(i) for i in model.geometric_links()} | {end_effector_link(model)}
    wanted |= {index[name] for name in attached_to if name in index}
    return sorted(wanted)


def path_frames(
    model: RobotModel,
    key_states: FloatArray,
    resolution: Resolution,
    links: list[int],
    *,
    max_frames: int = MAX_FRAMES,
) -> PathFrames:
    """The frames of the path through `key_states` (see the module docstring)."""
    key = np.asarray(key_states, dtype=float)
    samples = interpolate(key, model, resolution)
    count = len(samples)
    key_samples = np.zeros(len(key), dtype=np.int64)
    if len(key) > 1:
        key_samples[1:] = np.cumsum(sample_counts(key, model, resolution))
    picked = np.arange(count, dtype=np.int64)
    if count > max_frames:
        even = np.linspace(0, count - 1, max(max_frames - len(key), 2)).round().astype(np.int64)
        picked = np.union1d(even, key_samples)
    states = samples[picked]
    return PathFrames(
        states=states,
        sample=picked,
        samples=count,
        key=np.searchsorted(picked, key_samples),
        links=links,
        poses=np.round(link_poses(model, states, links), DIGITS),
    )


def frame_of(frames: PathFrames, sample: int) -> int:
    """The frame at validation sample `sample`, or the last one before it."""
    return max(int(np.searchsorted(frames.sample, sample, side="right")) - 1, 0)
