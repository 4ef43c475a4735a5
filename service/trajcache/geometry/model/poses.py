"""Link poses as a viewer takes them: position and unit quaternion, from the kinematics.

A pose is seven numbers, (x, y, z, qx, qy, qz, qw): what three.js, ROS messages and glTF read.
The world poses of links along a path come from `kinematics.forward_kinematics` (the base pose
of a planar base is part of the state), so what is drawn is where the validator put each link.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from trajcache.geometry.model.kinematics import check_states, forward_kinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import FloatArray

__all__ = ["link_poses", "pose7"]


def pose7(transforms: FloatArray) -> FloatArray:
    """(…, 4, 4) rigid transforms as (…, 7) poses: position, then quaternion (x, y, z, w)."""
    array = np.asarray(transforms, dtype=float)
    flat = array.reshape(-1, 4, 4)
    out = np.empty((len(flat), 7))
    out[:, :3] = flat[:, :3, 3]
    if len(flat):
        out[:, 3:] = Rotation.from_matrix(flat[:, :3, :3]).as_quat()
    return out.reshape(*array.shape[:-2], 7)


def link_poses(model: RobotModel, states: FloatArray, links: Sequence[int]) -> FloatArray:
    """World poses (N, K, 7) of `links` at each of the (N, D) `states`."""
    checked = check_states(model, states)
    transforms = forward_kinematics(model, checked)[:, np.asarray(links, dtype=np.int64)]
    return pose7(transforms)
