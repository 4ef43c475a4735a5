"""`moveit_msgs/MotionPlanRequest` as a rosbridge-style dict.

Every message lists all of its ROS fields and forbids others, so a misspelt field (a constraint
under a wrong name, say) is a 422 naming it instead of being dropped. Fields trajcache does not
use are typed loosely and ignored (the answer's warnings name them); fields it cannot honour
(path or trajectory constraints, reference trajectories, a Cartesian speed limit, attached
objects) are refused when not empty. Vectors and quaternions may be mappings (`{x: 1, y: 2,
z: 3}`) or lists in field order (`[x, y, z]`, `[x, y, z, w]`), as MoveIt's YAML tools write them.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import AfterValidator, ConfigDict, Field, field_validator, model_validator

from trajcache.core.planners import PLANNER_NAMES
from trajcache.core.request_model import RequestModel

Finite = Annotated[float, Field(allow_inf_nan=False)]
Name = Annotated[str, Field(max_length=200)]
Names = Annotated[list[Name], Field(max_length=256)]
Values = Annotated[list[Finite], Field(max_length=256)]
Loose = Annotated[list[dict[str, Any]], Field(max_length=256)]  # read, not interpreted

WRAPPERS = ("motion_plan_request", "request")  # GetMotionPlan's and MoveGroup's field names
# MoveIt/OMPL planner ids → native planner names (after "geometric::" and "kConfigDefault" go).
PLANNER_ALIASES = {"bitstar": "bitstar", "bit*": "bitstar", "kpiece1": "kpiece"}
PIPELINES = ("", "ompl")


def _not_supported(what: str) -> str:
    return f"{what} are not supported: trajcache cannot honour them, so it refuses them"


class _Message(RequestModel):
    model_config = ConfigDict(strict=True)


class _Components(_Message):
    """A message of plain components, also given as a list of them in field order."""

    @model_validator(mode="before")
    @classmethod
    def _from_list(cls, data: Any) -> Any:
        if not isinstance(data, list | tuple):
            return data
        names = list(cls.model_fields)
        if len(data) != len(names):
            raise ValueError(
                f"a list must have {len(names)} values ({', '.join(names)}), got {len(data)}"
            )
        return dict(zip(names, data, strict=True))


class Vector3(_Components):
    """`geometry_msgs/Vector3` (and `Point`): a mapping or `[x, y, z]`."""

    x: Finite = 0.0
    y: Finite = 0.0
    z: Finite = 0.0


class Quaternion(_Components):
    """`geometry_msgs/Quaternion`, a mapping or `[x, y, z, w]`; all zeros (a ROS 1 default)
    means identity."""

    x: Finite = 0.0
    y: Finite = 0.0
    z: Finite = 0.0
    w: Finite = 1.0


class Transform(_Message):
    """`geometry_msgs/Transform`."""

    translation: Vector3 = Field(default_factory=Vector3)
    rotation: Quaternion = Field(default_factory=Quaternion)


class Pose(_Message):
    """`geometry_msgs/Pose`, accepted in place of a Transform."""

    position: Vector3 = Field(default_factory=Vector3)
    orientation: Quaternion = Field(default_factory=Quaternion)


class JointState(_Message):
    """`sensor_msgs/JointState`: positions by name (velocity and effort are ignored)."""

    header: dict[str, Any] | None = None
    name: Names = []
    position: Values = []
    velocity: Values = []
    effort: Values = []

    @model_validator(mode="after")
    def _paired(self) -> JointState:
        if len(self.name) != len(self.position):
            raise ValueError(f"{len(self.name)} names but {len(self.position)} positions")
        return self


class MultiDOFJointState(_Message):
    """`sensor_msgs/MultiDOFJointState`; `poses` may replace `transforms`."""

    header: dict[str, Any] | None = None
    joint_names: Names = []
    transforms: Annotated[list[Transform], Field(max_length=256)] = []
    poses: Annotated[list[Pose], Field(max_length=256)] = []
    twist: Loose = []
    wrench: Loose = []

    @model_validator(mode="after")
    def _paired(self) -> MultiDOFJointState:
        given = max(len(self.transforms), len(self.poses))
        if len(self.joint_names) != given:
            raise ValueError(f"{len(self.joint_names)} joint names but {given} transforms")
        return self

    def planar(self, index: int) -> tuple[Vector3, Quaternion]:
        """Translation and rotation of joint `index`."""
        if self.transforms:
            t = self.transforms[index]
            return t.translation, t.rotation
        p = self.poses[index]
        return p.position, p.orientation


class RobotState(_Message):
    """`moveit_msgs/RobotState`. Attached objects belong to the robot's scene: here they are
    refused rather than ignored."""

    joint_state: JointState = Field(default_factory=JointState)
    multi_dof_joint_state: MultiDOFJointState = Field(default_factory=MultiDOFJointState)
    attached_collision_objects: Loose = Field(
        default=[],
        description="Not supported: must be empty (attach objects in the robot's scene).",
    )
    is_diff: bool = False

    @field_validator("attached_collision_objects")
    @classmethod
    def _no_attached_objects(cls, value: list[dict[str, Any]]) -> list[dict[str, Any]]:
        if value:
            raise ValueError(
                "attached collision objects are not supported in a plan request: attach them in "
                "the robot's scene (PUT /v1/robots/{robot_id}/scene), where they are validated"
            )
        return value


class JointConstraint(_Message):
    """`moveit_msgs/JointConstraint`."""

    joint_name: Name = ""
    position: Finite = 0.0
    tolerance_above: Finite = 0.0
    tolerance_below: Finite = 0.0
    weight: Finite = 1.0


class Constraints(_Message):
    """`moveit_msgs/Constraints`; as a goal, only joint constraints are supported."""

    name: Name = ""
    joint_constraints: Annotated[list[JointConstraint], Field(max_length=256)] = []
    position_constraints: Loose = []
    orientation_constraints: Loose = []
    visibility_constraints: Loose = []

    def other_kinds(self) -> list[str]:
        """The kinds of non-joint constraints it holds."""
        kinds = ("position_constraints", "orientation_constraints", "visibility_constraints")
        return [kind for kind in kinds if getattr(self, kind)]

    def is_empty(self) -> bool:
        """Whether it constrains nothing."""
        return not self.joint_constraints and not self.other_kinds()


def _empty_path_constraints(value: Constraints) -> Constraints:
    if not value.is_empty():
        raise ValueError(_not_supported("path constraints"))
    return value


def _no_cartesian_speed_limit(value: float) -> float:
    if value > 0:
        raise ValueError(_not_supported("Cartesian speed limits"))
    return value


# The fields every MoveIt request that moves a link carries and trajcache cannot honour.
NoPathConstraints = Annotated[
    Constraints,
    AfterValidator(_empty_path_constraints),
    Field(description="Not supported: must be empty."),
]
NoCartesianSpeed = Annotated[
    Finite,
    AfterValidator(_no_cartesian_speed_limit),
    Field(description="Not supported: a Cartesian speed limit must be ≤ 0 (off)."),
]


class TrajectoryConstraints(_Message):
    """`moveit_msgs/TrajectoryConstraints`."""

    constraints: Annotated[list[Constraints], Field(max_length=256)] = []


class MotionPlanRequestIn(_Message):
    """A `moveit_msgs/MotionPlanRequest` (ROS 1 or 2 field set), bare or wrapped as
    `{"motion_plan_request": {...}}` (GetMotionPlan) or `{"request": {...}}` (MoveGroup)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "group_name": "arm",
                    "start_state": {
                        "joint_state": {
                            "name": ["shoulder", "elbow"],
                            "position": [0.0, 0.0],
                        }
                    },
                    "goal_constraints": [
                        {
                            "joint_constraints": [
                                {"joint_name": "shoulder", "position": 1.0},
                                {"joint_name": "elbow", "position": 0.5},
                            ]
                        }
                    ],
                    "planner_id": "RRTConnectkConfigDefault",
                    "allowed_planning_time": 2.0,
                    "max_velocity_scaling_factor": 0.5,
                    "max_acceleration_scaling_factor": 0.5,
                }
            ]
        }
    )

    workspace_parameters: dict[str, Any] | None = Field(default=None, description="Ignored.")
    start_state: RobotState = Field(default_factory=RobotState)
    goal_constraints: Annotated[list[Constraints], Field(max_length=64)] = Field(
        default=[],
        description="The first whose joint constraints cover every planning joint is the goal.",
    )
    path_constraints: NoPathConstraints = Field(default_factory=Constraints)
    trajectory_constraints: TrajectoryConstraints = Field(
        default_factory=TrajectoryConstraints, description="Not supported: must be empty."
    )
    reference_trajectories: Loose = Field(default=[], description="Not supported: must be empty.")
    pipeline_id: Name = Field(default="", description="Empty or 'ompl'.")
    planner_id: Name = Field(
        default="",
        description="A trajcache planner (" + ", ".join(PLANNER_NAMES) + "), case-insensitive, "
        "or a MoveIt/OMPL id such as 'RRTConnectkConfigDefault', 'geometric::BITstar'; MoveIt's "
        "RRTConnect ids (any spelling but the native 'rrtconnect') and empty: the service "
        "default; any other id: the service default, with a warning.",
    )
    group_name: Name = Field(default="", description="Echoed in the response.")
    num_planning_attempts: int = Field(default=0, ge=0, description="Ignored.")
    allowed_planning_time: Finite = Field(
        default=0.0,
        ge=0,
        description="Planning budget (s); 0: the service default; above plan_budget_max_s: "
        "plan_budget_max_s, with a warning.",
    )
    max_velocity_scaling_factor: Finite = Field(
        default=0.0, ge=0, le=1, description="Factor on velocity limits, 0 < f ≤ 1; 0 means 1."
    )
    max_acceleration_scaling_factor: Finite = Field(
        default=0.0, ge=0, le=1, description="Factor on acceleration limits; 0 means 1."
    )
    cartesian_speed_limited_link: Name = ""
    cartesian_speed_end_effector_link: Name = ""
    max_cartesian_speed: NoCartesianSpeed = 0.0

    @model_validator(mode="before")
    @classmethod
    def _unwrap(cls, data: Any) -> Any:
        if isinstance(data, dict) and len(data) == 1:
            (key, inner), *_ = data.items()
            if key in WRAPPERS:
                return inner
        return data

    @field_validator("trajectory_constraints")
    @classmethod
    def _no_trajectory_constraints(cls, value: TrajectoryConstraints) -> TrajectoryConstraints:
        if any(not c.is_empty() for c in value.constraints):
            raise ValueError(_not_supported("trajectory constraints"))
        return value

    @field_validator("reference_trajectories")
    @classmethod
    def _no_reference_trajectories(cls, value: list[dict[str, Any]]) -> list[dict[str, Any]]:
        if value:
            raise ValueError(_not_supported("reference trajectories"))
        return value

    @field_validator("pipeline_id")
    @classmethod
    def _ompl_pipeline(cls, value: str) -> str:
        if value.strip().lower() not in PIPELINES:
            raise ValueError(f"pipeline {value!r} is not served; leave it empty or use 'ompl'")
        return value


def known_planner(planner_id: str) -> str | None:
    """The native planner name of a MoveIt/OMPL planner id ('' stays ''); None if it names none.

    Only exact names count (after `geometric::` and `kConfigDefault` go, in any case): an id is
    never guessed from a prefix, so `BKPIECEGood` or `LBKPIECE1` name no planner here. MoveIt's
    own RRTConnect ids (`RRTConnect`, `RRTConnectkConfigDefault`, `geometric::RRTConnect`: any
    spelling but the native `rrtconnect`) mean the service's default planner, the compiled
    RRT-Connect, which plans the same way; `rrtconnect` in lower case names OMPL's."""
    given = planner_id.strip().lower()
    key = given.removeprefix("geometric::").removesuffix("kconfigdefault")
    if key == "rrtconnect" and planner_id.strip() != "rrtconnect":
        return ""
    key = PLANNER_ALIASES.get(key, key)
    return key if not given or key in PLANNER_NAMES else None


def native_planner(planner_id: str) -> str:
    """The native planner name of a MoveIt/OMPL planner id ('' stays ''); ValueError if none."""
    key = known_planner(planner_id)
    if key is None:
        known = ", ".join(PLANNER_NAMES)
        raise ValueError(
            f"unknown planner {planner_id!r}; use one of {known} (any case), or their OMPL ids "
            "such as RRTConnect, RRTConnectkConfigDefault, geometric::BITstar"
        )
    return key
