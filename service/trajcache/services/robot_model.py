"""The model behind a robot id, for requests that must read joint names before the plan flow."""

from __future__ import annotations

from trajcache.geometry.model.robot import RobotModel
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import get_robot, held_values
from trajcache.services.context import ServiceContext


def robot_model(*, ctx: ServiceContext, robot_id: str) -> RobotModel:
    """The model of robot `robot_id` (NotFoundError when unknown); one query when it is cached."""
    return robot_model_and_held(ctx=ctx, robot_id=robot_id)[0]


def robot_model_and_held(
    *, ctx: ServiceContext, robot_id: str
) -> tuple[RobotModel, dict[str, float]]:
    """The model of robot `robot_id` and the joint values the robot holds otherwise than its
    model (empty: as the model holds them); NotFoundError when unknown."""
    with ctx.sessions() as session:
        robot = get_robot(session=session, robot_id=robot_id)
        model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        return model, held_values(robot.joint_values) or {}
