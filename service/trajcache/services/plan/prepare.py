"""A robot's new scene made ready for its next request: the scene's collision validator, built
once the scene is written, after its answer is sent (a background task of the scene routes).

Every plan, hit, IK and Cartesian request checks against `validator_for(model in the scene,
scene, settings)`, built on first use and shared (`ValidatorCache`). After a scene change the
first request built it on its own time (0.5 ms for an MBM scene and the Panda, more for a large
scene). Here it is built as a request builds it, under the same key (the robot's model as it
holds its joints in the scene, the scene's hash, the validation settings), so the request finds
it ready. Nothing is decided here: a request that comes first builds it itself, and a scene
changed again in the meantime only leaves an unused validator in the cache. An error is logged,
never answered (the scene write has been answered already).
"""

from __future__ import annotations

import logging

from trajcache.geometry.scene.variant import model_in_scene
from trajcache.geometry.validation.validator import validator_for
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.robots import robot_scene
from trajcache.services.context import ServiceContext

__all__ = ["prepare_scene"]

logger = logging.getLogger(__name__)


def prepare_scene(ctx: ServiceContext, robot_id: str) -> None:
    """Build the validator of robot `robot_id`'s current scene, as its next request would."""
    try:
        with ctx.sessions() as session:
            robot = robot_scene(session=session, scenes=ctx.scenes, robot_id=robot_id)
            model = get_model(session=session, registry=ctx.models, model_id=robot.model_id)
        checked = model_in_scene(model, robot.scene, robot.joint_values, cache=ctx.variants)
        validator_for(checked, robot.scene, ctx.settings, cache=ctx.validators)
    except Exception:  # the robot deleted since, a model that no longer loads: the request says
        logger.warning("preparing robot %r's new scene failed", robot_id, exc_info=True)
