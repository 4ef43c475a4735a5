"""What of a MotionPlanRequest is read differently from MoveIt, or ignored: the answer's warnings.

- `planner_id` naming no planner of the service (exact names only, never a prefix): the
  service's default planner plans;
- `allowed_planning_time` above `plan_budget_max_s`: clamped to it;
- given and ignored: `workspace_parameters`, `num_planning_attempts` above 1 (one attempt
  plans), `cartesian_speed_*_link`, `group_name` (the model's planning joints are those it was
  registered with), the joint state's `velocity` and `effort`, and a fixed base's
  `multi_dof_joint_state`.
"""

from __future__ import annotations

from trajcache.api.moveit._messages import MotionPlanRequestIn, known_planner
from trajcache.core.config import Settings
from trajcache.geometry.model.robot import BaseType


def planner_and_budget(
    message: MotionPlanRequestIn, settings: Settings, warnings: list[str]
) -> tuple[str | None, float | None]:
    """The native planner (None: the default) and budget (None: the default) of `message`."""
    planner = known_planner(message.planner_id)
    if planner is None:
        warnings.append(
            f"planner_id {message.planner_id!r} is not a planner of this service: planned with "
            f"its default planner {settings.default_planner!r}"
        )
    budget = message.allowed_planning_time or None  # 0 s: the default budget
    if budget is not None and budget > settings.plan_budget_max_s:
        warnings.append(
            f"allowed_planning_time {budget:g} s is above the service's maximum: planned with "
            f"plan_budget_max_s={settings.plan_budget_max_s:g} s"
        )
        budget = settings.plan_budget_max_s
    return planner or None, budget


def ignored_fields(message: MotionPlanRequestIn, base: BaseType) -> list[str]:
    """A warning for each field the request gives that is not used."""
    joints = message.start_state.joint_state
    multi_dof = message.start_state.multi_dof_joint_state
    given = {
        "workspace_parameters": bool(message.workspace_parameters),
        "num_planning_attempts": message.num_planning_attempts > 1,
        "cartesian_speed_limited_link": bool(message.cartesian_speed_limited_link),
        "cartesian_speed_end_effector_link": bool(message.cartesian_speed_end_effector_link),
        "start_state.joint_state.velocity": bool(joints.velocity),
        "start_state.joint_state.effort": bool(joints.effort),
        "start_state.multi_dof_joint_state.twist": bool(multi_dof.twist),
        "start_state.multi_dof_joint_state.wrench": bool(multi_dof.wrench),
    }
    out = [f"{name} is ignored" for name, present in given.items() if present]
    if message.num_planning_attempts > 1:
        out[out.index("num_planning_attempts is ignored")] += " (one attempt plans)"
    if base is BaseType.FIXED and multi_dof.joint_names:
        out.append("start_state.multi_dof_joint_state is ignored: the robot's base is fixed")
    if message.group_name:
        out.append(
            f"group_name {message.group_name!r} does not choose the joints: the robot plans the "
            "planning joints its model was registered with"
        )
    return out
