"""The MotionPlanResponse's schemas: ROS messages as rosbridge-style dicts, plus trajcache's extras.

Named `...Out` like every response schema of the API (and apart from the native JointTrajectory).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class Vector3Out(BaseModel):
    """`geometry_msgs/Vector3`."""

    x: float
    y: float
    z: float


class QuaternionOut(BaseModel):
    """`geometry_msgs/Quaternion`."""

    x: float
    y: float
    z: float
    w: float


class TransformOut(BaseModel):
    """`geometry_msgs/Transform`."""

    translation: Vector3Out
    rotation: QuaternionOut


class DurationOut(BaseModel):
    """`builtin_interfaces/Duration`."""

    sec: int
    nanosec: int


class JointTrajectoryPointOut(BaseModel):
    """`trajectory_msgs/JointTrajectoryPoint`."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    time_from_start: DurationOut


class JointTrajectoryOut(BaseModel):
    """`trajectory_msgs/JointTrajectory`: the planning joints (a planar base is not here)."""

    joint_names: list[str]
    points: list[JointTrajectoryPointOut]


class TwistOut(BaseModel):
    """`geometry_msgs/Twist`, in the world frame."""

    linear: Vector3Out
    angular: Vector3Out


class MultiDOFJointTrajectoryPointOut(BaseModel):
    """`trajectory_msgs/MultiDOFJointTrajectoryPoint`."""

    transforms: list[TransformOut]
    velocities: list[TwistOut]
    accelerations: list[TwistOut]
    time_from_start: DurationOut


class MultiDOFJointTrajectoryOut(BaseModel):
    """`trajectory_msgs/MultiDOFJointTrajectory`: the planar base, when the model has one."""

    joint_names: list[str]
    points: list[MultiDOFJointTrajectoryPointOut]


class RobotTrajectoryOut(BaseModel):
    """`moveit_msgs/RobotTrajectory`."""

    joint_trajectory: JointTrajectoryOut
    multi_dof_joint_trajectory: MultiDOFJointTrajectoryOut


class JointStateOut(BaseModel):
    """`sensor_msgs/JointState` (positions only)."""

    name: list[str]
    position: list[float]


class MultiDOFJointStateOut(BaseModel):
    """`sensor_msgs/MultiDOFJointState` (transforms only)."""

    joint_names: list[str]
    transforms: list[TransformOut]


class RobotStateOut(BaseModel):
    """`moveit_msgs/RobotState`."""

    joint_state: JointStateOut
    multi_dof_joint_state: MultiDOFJointStateOut


class ErrorCodeOut(BaseModel):
    """`moveit_msgs/MoveItErrorCodes` (`message` and `source` as in MoveIt 2)."""

    val: int
    message: str
    source: str


class CandidateRejectionOut(BaseModel):
    """A cached candidate that failed validation, and why."""

    trajectory_id: int
    status: str
    reason: str


class TrajcacheExtrasOut(BaseModel):
    """Where the answer came from, for operators (not part of MoveIt's message)."""

    status: Literal["success", "miss", "failure", "invalid"] = Field(
        description="The native plan status; 'invalid': refused before planning (the native "
        "endpoint's 422), the error code says why."
    )
    source: Literal["cache", "planner", "repaired"] | None
    trajectory_id: int | None
    candidates_tried: int
    timings_ms: dict[str, float]
    message: str
    rejected: list[CandidateRejectionOut]
    quality: dict[str, float | None] | None


class MotionPlanResponseOut(BaseModel):
    """A `moveit_msgs/MotionPlanResponse`, plus `trajcache`: where the answer came from."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "trajectory_start": {
                        "joint_state": {"name": ["shoulder", "elbow"], "position": [0.0, 0.0]},
                        "multi_dof_joint_state": {"joint_names": [], "transforms": []},
                    },
                    "group_name": "arm",
                    "trajectory": {
                        "joint_trajectory": {
                            "joint_names": ["shoulder", "elbow"],
                            "points": [
                                {
                                    "positions": [0.0, 0.0],
                                    "velocities": [0.0, 0.0],
                                    "accelerations": [1.25, 0.625],
                                    "time_from_start": {"sec": 0, "nanosec": 0},
                                },
                                {
                                    "positions": [1.0, 0.5],
                                    "velocities": [0.0, 0.0],
                                    "accelerations": [-1.25, -0.625],
                                    "time_from_start": {"sec": 1, "nanosec": 789000000},
                                },
                            ],
                        },
                        "multi_dof_joint_trajectory": {"joint_names": [], "points": []},
                    },
                    "planning_time": 0.004,
                    "error_code": {"val": 1, "message": "", "source": "trajcache"},
                    "warnings": [],
                    "trajcache": {
                        "status": "success",
                        "source": "cache",
                        "trajectory_id": 12,
                        "candidates_tried": 1,
                        "timings_ms": {"lookup": 0.3, "validate": 0.9, "total": 2.4},
                        "message": "",
                        "rejected": [],
                        "quality": {
                            "path_length": 1.118,
                            "ee_path_length": 0.52,
                            "min_clearance": None,
                            "duration_s": 1.789,
                        },
                    },
                }
            ]
        }
    )

    trajectory_start: RobotStateOut
    group_name: str
    trajectory: RobotTrajectoryOut
    planning_time: float = Field(description="Seconds spent in the service on this request.")
    error_code: ErrorCodeOut
    warnings: list[str] = Field(
        description="What of the request was read differently from MoveIt (an unknown "
        "planner_id, a clamped allowed_planning_time, a start or goal moved onto a joint limit, "
        "fixed joints) or ignored.",
    )
    trajcache: TrajcacheExtrasOut
