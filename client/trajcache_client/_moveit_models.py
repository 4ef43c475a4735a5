"""The MoveIt answer of /v1/robots/{robot_id}/motion-plan, typed as the plain mappings it is.

The answer is a ROS message, so it stays a dict (ready for ROS tooling); these TypedDicts give
its keys and value types to type checkers without copying it into models.
"""

from __future__ import annotations

from typing import Literal, TypedDict


class Vector3(TypedDict):
    """`geometry_msgs/Vector3`."""

    x: float
    y: float
    z: float


class Quaternion(TypedDict):
    """`geometry_msgs/Quaternion`."""

    x: float
    y: float
    z: float
    w: float


class Transform(TypedDict):
    """`geometry_msgs/Transform`."""

    translation: Vector3
    rotation: Quaternion


class Twist(TypedDict):
    """`geometry_msgs/Twist`."""

    linear: Vector3
    angular: Vector3


class Duration(TypedDict):
    """`builtin_interfaces/Duration`."""

    sec: int
    nanosec: int


class JointState(TypedDict):
    """`sensor_msgs/JointState` (positions only)."""

    name: list[str]
    position: list[float]


class MultiDOFJointState(TypedDict):
    """`sensor_msgs/MultiDOFJointState` (transforms only)."""

    joint_names: list[str]
    transforms: list[Transform]


class RobotState(TypedDict):
    """`moveit_msgs/RobotState`."""

    joint_state: JointState
    multi_dof_joint_state: MultiDOFJointState


class MoveItJointTrajectoryPoint(TypedDict):
    """`trajectory_msgs/JointTrajectoryPoint`."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    time_from_start: Duration


class MoveItJointTrajectory(TypedDict):
    """`trajectory_msgs/JointTrajectory`."""

    joint_names: list[str]
    points: list[MoveItJointTrajectoryPoint]


class MultiDOFJointTrajectoryPoint(TypedDict):
    """`trajectory_msgs/MultiDOFJointTrajectoryPoint`."""

    transforms: list[Transform]
    velocities: list[Twist]
    accelerations: list[Twist]
    time_from_start: Duration


class MultiDOFJointTrajectory(TypedDict):
    """`trajectory_msgs/MultiDOFJointTrajectory`."""

    joint_names: list[str]
    points: list[MultiDOFJointTrajectoryPoint]


class RobotTrajectory(TypedDict):
    """`moveit_msgs/RobotTrajectory`."""

    joint_trajectory: MoveItJointTrajectory
    multi_dof_joint_trajectory: MultiDOFJointTrajectory


class MoveItErrorCode(TypedDict):
    """`moveit_msgs/MoveItErrorCodes` (`val` 1: SUCCESS; `message`, `source` as in MoveIt 2)."""

    val: int
    message: str
    source: str


class CandidateRejection(TypedDict):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class TrajcacheExtras(TypedDict):
    """Where the answer came from ("invalid": refused before planning), for operators."""

    status: Literal["success", "miss", "failure", "invalid"] | str
    source: Literal["cache", "planner", "repaired"] | str | None
    trajectory_id: int | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str
    rejected: list[CandidateRejection]
    quality: dict[str, float | None] | None


class MotionPlanResponse(TypedDict):
    """`moveit_msgs/MotionPlanResponse`, plus `trajcache`: where the answer came from."""

    trajectory_start: RobotState
    group_name: str
    trajectory: RobotTrajectory
    planning_time: float
    error_code: MoveItErrorCode
    warnings: list[str]
    trajcache: TrajcacheExtras


class TrajcacheIkExtras(TypedDict):
    """How the native IK answered ("invalid": refused before solving), for operators."""

    status: Literal["success", "not_found", "in_collision", "invalid"] | str
    message: str
    warnings: list[str]
    link: str | None
    position_error: float | None
    orientation_error: float | None
    timings_ms: dict[str, float]


class GetPositionIKResponse(TypedDict):
    """`moveit_msgs/GetPositionIK` response (`error_code.val` -31: no solution), plus
    `trajcache`: how it was answered."""

    solution: RobotState
    error_code: MoveItErrorCode
    trajcache: TrajcacheIkExtras


class TrajcacheCartesianExtras(TypedDict):
    """How the native Cartesian path answered ("invalid": refused before computing)."""

    status: (
        Literal[
            "complete",
            "no_ik_solution",
            "joint_jump",
            "collision",
            "too_close",
            "out_of_limits",
            "invalid",
        ]
        | str
    )
    source: Literal["computed", "cache"] | str | None
    message: str
    warnings: list[str]
    link: str | None
    max_deviation_m: float | None
    path_id: int | None
    timings_ms: dict[str, float]


class GetCartesianPathResponse(TypedDict):
    """`moveit_msgs/GetCartesianPath` response (`error_code.val` 1 with any `fraction`), plus
    `trajcache`: how it was answered."""

    start_state: RobotState
    solution: RobotTrajectory
    fraction: float
    error_code: MoveItErrorCode
    trajcache: TrajcacheCartesianExtras
