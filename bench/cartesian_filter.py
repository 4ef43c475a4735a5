"""Which straight hand moves of the MBM Panda are feasible, judged without the service.

A move is feasible when an independent IK path exists along its line and the whole robot is
clear along it: from the start state, samples of the line (every 1 cm, the orientation held;
halved down to LINE_STEP_M / 2**REFINE where a joint would move by more than MAX_JOINT_STEP, so
that the path stays on one branch through near-singular stretches) are solved by damped least
squares from the previous sample's solution (Pinocchio, from the shipped URDF; a joint at its
URDF limit that a step would push out is held there and the others take up the motion), and
the path's key states are dense-checked with every link (`mbm_check`: meshes, self-collision,
the scene's allowed pairs).
A move is then filtered out for one reason, in this order:

- `start_in_collision`: the start state itself touches something;
- `no_ik_along_line`: a sample has no solution near the previous one within the joint limits
  (a limit or a singularity stops the hand on its line);
- `arm_blocked`: the arm (not only the hand) hits an object or itself along the path.

The IK path is one witness: a redundant arm has others, so a service may find a clear path where
this one is blocked (it counts as a bonus, not a miss) or be blocked where this one is clear.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mbm_check import SceneChecker

LINE_STEP_M = 0.01
POSITION_TOLERANCE = 1e-5  # m
ORIENTATION_TOLERANCE = 1e-4  # rad
ITERATIONS = 200
DAMPING = 1e-6
MAX_JOINT_STEP = 0.1  # rad between key states
REFINE = 6


class LineIk:
    """Damped least-squares IK of one frame of the checker's Pinocchio model, warm-started."""

    def __init__(self, checker: SceneChecker, link: str) -> None:
        self.checker = checker
        self.frame = checker.model.getFrameId(link)
        model = checker.model
        self.columns = [model.joints[j].idx_v for j in checker.joint_ids]

    def pose(self, state: np.ndarray) -> pin.SE3:
        model, data = self.checker.model, self.checker.data
        pin.framesForwardKinematics(model, data, self.checker.configuration(state))
        return data.oMf[self.frame].copy()

    def solve(self, seed: np.ndarray, target: pin.SE3) -> np.ndarray | None:
        """A state within the limits putting the frame at `target`, near `seed`; None if none."""
        model, data = self.checker.model, self.checker.data
        state = seed.copy()
        for _ in range(ITERATIONS):
            q = self.checker.configuration(state)
            pin.framesForwardKinematics(model, data, q)
            error = pin.log6(data.oMf[self.frame].actInv(target)).vector
            if (
                np.linalg.norm(error[:3]) < POSITION_TOLERANCE
                and np.linalg.norm(error[3:]) < ORIENTATION_TOLERANCE
            ):
                return state
            jacobian = pin.computeFrameJacobian(model, data, q, self.frame, pin.LOCAL)
            state = np.clip(
                state + self._step(jacobian[:, self.columns], error, state), *self.limits
            )
        return None

    @property
    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        return self.checker.lower, self.checker.upper

    def _step(self, j: np.ndarray, error: np.ndarray, state: np.ndarray) -> np.ndarray:
        """The damped least-squares step, joints held where it would push them out of limits."""
        step = j.T @ np.linalg.solve(j @ j.T + DAMPING * np.eye(6), error)
        lower, upper = self.limits
        held = ((state <= lower + 1e-9) & (step < 0)) | ((state >= upper - 1e-9) & (step > 0))
        if held.any():
            free = j[:, ~held]
            step[:] = 0.0
            step[~held] = free.T @ np.linalg.solve(free @ free.T + DAMPING * np.eye(6), error)
        return step

    def along(self, start: np.ndarray, shift: np.ndarray) -> np.ndarray | None:
        """The IK path of the frame moved by `shift` on a straight line, orientation held."""
        origin = self.pose(start)
        step = base = LINE_STEP_M / max(float(np.linalg.norm(shift)), LINE_STEP_M)
        states, t = [start], 0.0
        while t < 1.0:
            reach = min(1.0, t + step)
            target = pin.SE3(origin.rotation, origin.translation + reach * shift)
            found = self.solve(states[-1], target)
            if found is None or np.abs(found - states[-1]).max() > MAX_JOINT_STEP:
                if step < base / 2**REFINE:
                    return None  # no solution, or a branch that does not continue
                step /= 2
                continue
            states.append(found)
            t, step = reach, min(base, 2 * step)
        return np.array(states)


def infeasible_reason(ik: LineIk, start: np.ndarray, shift: np.ndarray) -> str:
    """Why the move cannot be made (module docstring), or "" when it can."""
    return line_witness(ik, start, shift)[0]


def line_witness(ik: LineIk, start: np.ndarray, shift: np.ndarray) -> tuple[str, np.ndarray]:
    """Why the move cannot be made ("" when it can), and the witness's IK path (key states;
    empty when there is none)."""
    checker = ik.checker
    if not checker.is_free(start):
        return "start_in_collision", np.empty((0, len(start)))
    states = ik.along(start, shift)
    if states is None:
        return "no_ik_along_line", np.empty((0, len(start)))
    verdict = checker.check_path(states)
    if verdict.collides or verdict.self_collides:
        return "arm_blocked", states
    return "", states
