"""MoveIt error codes, and the code of each way a native plan can end.

Native outcome → code:

- a plan answered with a path → SUCCESS;
- a pose goal that no free state reaches (`services.plan.pose_goal`) → NO_IK_SOLUTION;
- no valid cached trajectory and no planning (`miss`) → PLANNING_FAILED;
- the planner's failure, by the planner status its message begins with: `timeout` (no path at
  all within the budget) → TIMED_OUT, `uncertified` (paths found, none certified) →
  PLANNING_FAILED, `invalid_start` / `invalid_goal` (the endpoint collides, or is too close to
  certify) →
  START_STATE_IN_COLLISION / GOAL_IN_COLLISION, a planned path that failed validation →
  INVALID_MOTION_PLAN, anything else → PLANNING_FAILED;
- a StateError the flow raised (the native endpoint's 422s): a collision of the start or goal →
  START_STATE_IN_COLLISION / GOAL_IN_COLLISION, any other bad goal → INVALID_GOAL_CONSTRAINTS,
  any other bad start → INVALID_ROBOT_STATE (the flow names the state first in its messages).
- a robot that never uploaded a scene, under `require_scene` (the native endpoint's 409) →
  COLLISION_CHECKING_UNAVAILABLE: there is no world to check the path against.
"""

from __future__ import annotations

from enum import IntEnum

from trajcache.geometry.errors import CollisionStateError, StateError
from trajcache.planning.problem import PlannerStatus
from trajcache.services.errors import SceneRequiredError
from trajcache.services.plan.flow import PlanAnswer, PlanStatus
from trajcache.services.plan.pose_goal import NO_GOAL_STATE

VALIDATION_FAILED = "planned path failed validation"  # services.plan.flow's message


class MoveItErrorCode(IntEnum):
    """The values of `moveit_msgs/MoveItErrorCodes` that trajcache answers with."""

    SUCCESS = 1
    FAILURE = 99999
    PLANNING_FAILED = -1
    INVALID_MOTION_PLAN = -2
    TIMED_OUT = -6
    START_STATE_IN_COLLISION = -10
    GOAL_IN_COLLISION = -12
    INVALID_GOAL_CONSTRAINTS = -16
    INVALID_ROBOT_STATE = -17
    FRAME_TRANSFORM_FAILURE = -21
    COLLISION_CHECKING_UNAVAILABLE = -22
    NO_IK_SOLUTION = -31


class MotionPlanError(Exception):
    """A well-formed request that cannot be planned: answered 200 with a MoveIt error code."""

    def __init__(self, code: MoveItErrorCode, message: str) -> None:
        super().__init__(message)
        self.code = code


_PLANNER_CODES = {
    PlannerStatus.TIMEOUT: MoveItErrorCode.TIMED_OUT,
    PlannerStatus.UNCERTIFIED: MoveItErrorCode.PLANNING_FAILED,
    PlannerStatus.INVALID_START: MoveItErrorCode.START_STATE_IN_COLLISION,
    PlannerStatus.INVALID_GOAL: MoveItErrorCode.GOAL_IN_COLLISION,
}


def answer_code(answer: PlanAnswer) -> MoveItErrorCode:
    """The code of a native plan answer."""
    if answer.status is PlanStatus.SUCCESS:
        return MoveItErrorCode.SUCCESS
    if answer.status is PlanStatus.MISS:
        return MoveItErrorCode.PLANNING_FAILED
    if answer.status is PlanStatus.FAILURE:
        if answer.message.startswith(NO_GOAL_STATE):  # a pose goal no free state reaches
            return MoveItErrorCode.NO_IK_SOLUTION
        if answer.message.startswith(VALIDATION_FAILED):
            return MoveItErrorCode.INVALID_MOTION_PLAN
        try:
            status = PlannerStatus(answer.message.split(":", 1)[0].strip())
        except ValueError:
            return MoveItErrorCode.PLANNING_FAILED
        return _PLANNER_CODES.get(status, MoveItErrorCode.PLANNING_FAILED)
    return MoveItErrorCode.FAILURE


def state_error_code(error: StateError | SceneRequiredError) -> MoveItErrorCode:
    """The code of a start or goal the plan flow refused, or of a robot it refused (no scene)."""
    if isinstance(error, SceneRequiredError):
        return MoveItErrorCode.COLLISION_CHECKING_UNAVAILABLE
    goal = str(error).startswith("goal")
    if isinstance(error, CollisionStateError):
        return (
            MoveItErrorCode.GOAL_IN_COLLISION if goal else MoveItErrorCode.START_STATE_IN_COLLISION
        )
    return MoveItErrorCode.INVALID_GOAL_CONSTRAINTS if goal else MoveItErrorCode.INVALID_ROBOT_STATE
