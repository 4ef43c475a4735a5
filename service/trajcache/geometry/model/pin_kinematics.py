"""The robot model in Pinocchio, built from the URDF the service registered, and the map between
the service's state vector and Pinocchio's configuration q.

Pinocchio parses the URDF text itself (no meshes: kinematics only). A planar base is a
`JointModelPlanar` root joint (q = x, y, cos θ, sin θ; its velocity is in the base frame). Every
movable URDF joint is a Pinocchio joint, so a mimic joint is an independent joint there: its value
is set from its leader's (multiplier · leader + offset), and its Jacobian column is added to the
leader's, scaled by the multiplier. Joints outside the planning joints are held at the values of
the `RobotModel` the map is built for (the robot's held values, when it is the robot's variant).
Continuous joints take (cos, sin) in q. So, for a state s:

    q = q(s),   ∂(frame twist)/∂s = J(q) · V(s)

with V (nv × dof) holding the multipliers, and for the planar base the rotation from world to
base axes (x, y) and 1 for θ. `tests/geometry/test_pin_kinematics.py` checks that every link's
pose agrees with `kinematics.link_transforms` on every supported robot. Nothing is cached here:
the service keeps what it builds (`ServiceContext.kinematics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from trajcache.geometry.errors import RobotModelError
from trajcache.geometry.model.robot import BaseType, RobotModel
from trajcache.geometry.model.shapes import FloatArray


def _pin_model(urdf: str, planar: bool) -> pin.Model:
    """Pinocchio's model of a URDF text (kinematics only: no meshes are read)."""
    try:
        if planar:
            return pin.buildModelFromXML(urdf, pin.JointModelPlanar())
        return pin.buildModelFromXML(urdf)
    except (RuntimeError, ValueError) as exc:
        raise RobotModelError(f"Pinocchio cannot read the URDF: {exc}") from exc


@dataclass(frozen=True, eq=False)
class PinKinematics:
    """A `RobotModel` in Pinocchio: q of a state, link poses, and link Jacobians by state."""

    model: RobotModel
    pin_model: pin.Model
    q_neutral: FloatArray  # held values and zeros
    q_single: np.ndarray  # q index of each 1-value joint mapped from the state
    q_cos: np.ndarray  # q indices (cos, sin) of each continuous joint mapped from the state
    q_sin: np.ndarray
    single_from: np.ndarray  # the state column each joint reads (same order as q_single)
    single_scale: FloatArray
    single_offset: FloatArray
    cont_from: np.ndarray
    cont_scale: FloatArray
    cont_offset: FloatArray
    velocity_map: FloatArray  # V without the planar base's rotation (nv × dof)
    _frames: dict[str, int] = field(default_factory=dict, repr=False)  # frame ids by link

    @classmethod
    def build(cls, model: RobotModel, urdf: str) -> PinKinematics:
        """The map for `model`, whose URDF text is `urdf` (the one it was registered with)."""
        planar = model.base is BaseType.PLANAR
        pmodel = _pin_model(urdf, planar)
        q0 = np.array(pin.neutral(pmodel), dtype=float)
        single: list[tuple[int, int, float, float]] = []
        cont: list[tuple[int, int, float, float]] = []
        vmap = np.zeros((pmodel.nv, model.dof))
        if planar:
            vmap[0:3, 0:3] = np.eye(3)
        for joint in model.joints:
            if joint.kind == "fixed":
                continue
            if not pmodel.existJointName(joint.name):
                raise RobotModelError(f"Pinocchio's model lacks joint {joint.name!r}")
            pj = pmodel.joints[pmodel.getJointId(joint.name)]
            index = joint.index  # a state column (after a planar base's), or -1: held
            if pj.nq == 2:
                _set_angle(q0, pj.idx_q, joint.default)
            else:
                q0[pj.idx_q] = joint.default
            if index < 0:
                continue
            entry = (pj.idx_q, index, joint.scale, joint.offset)
            (cont if pj.nq == 2 else single).append(entry)
            vmap[pj.idx_v, index] += joint.scale
        return cls(
            model=model,
            pin_model=pmodel,
            q_neutral=q0,
            q_single=np.array([e[0] for e in single], dtype=np.int64),
            q_cos=np.array([e[0] for e in cont], dtype=np.int64),
            q_sin=np.array([e[0] + 1 for e in cont], dtype=np.int64),
            single_from=np.array([e[1] for e in single], dtype=np.int64),
            single_scale=np.array([e[2] for e in single], dtype=float),
            single_offset=np.array([e[3] for e in single], dtype=float),
            cont_from=np.array([e[1] for e in cont], dtype=np.int64),
            cont_scale=np.array([e[2] for e in cont], dtype=float),
            cont_offset=np.array([e[3] for e in cont], dtype=float),
            velocity_map=vmap,
        )

    def frame_id(self, link: str) -> int:
        """Pinocchio's frame of link `link`; RobotModelError when the model has no such link.
        Found once per link (Pinocchio searches its frames by name)."""
        found = self._frames.get(link)
        if found is None:
            if link not in self.model.link_names or not self.pin_model.existFrame(link, pin.BODY):
                raise RobotModelError(f"no link {link!r} in the model")
            found = self._frames[link] = int(self.pin_model.getFrameId(link, pin.BODY))
        return found

    def q_of(self, state: FloatArray) -> FloatArray:
        """Pinocchio's configuration of a state (values in `state_names` order)."""
        q = self.q_neutral.copy()
        q[self.q_single] = self.single_scale * state[self.single_from] + self.single_offset
        if len(self.q_cos):
            angle = self.cont_scale * state[self.cont_from] + self.cont_offset
            q[self.q_cos], q[self.q_sin] = np.cos(angle), np.sin(angle)
        if self.model.base is BaseType.PLANAR:
            q[0], q[1] = state[0], state[1]
            _set_angle(q, 2, state[2])
        return q

    def velocity_of(self, state: FloatArray) -> FloatArray:
        """V(s): Pinocchio's joint velocity of a unit rate of each state value (nv × dof)."""
        if self.model.base is not BaseType.PLANAR:
            return self.velocity_map
        v = self.velocity_map.copy()
        c, s = math.cos(state[2]), math.sin(state[2])
        v[0:2, 0:2] = ((c, s), (-s, c))  # world (ẋ, ẏ) in the base's axes
        return v

    def link_pose(self, state: FloatArray, frame: int) -> FloatArray:
        """World pose (4×4) of frame `frame` at `state`."""
        data = self.pin_model.createData()
        pin.forwardKinematics(self.pin_model, data, self.q_of(state))
        return np.array(pin.updateFramePlacement(self.pin_model, data, frame).homogeneous)


def _set_angle(q: FloatArray, at: int, angle: float) -> None:
    q[at], q[at + 1] = math.cos(angle), math.sin(angle)
