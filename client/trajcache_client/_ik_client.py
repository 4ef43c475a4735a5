"""The IK methods of `Client` and `AsyncClient` (each a one-line call of its operation)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from trajcache_client import _ik_operations as ops
from trajcache_client._models import IkResult
from trajcache_client._moveit_models import GetPositionIKResponse
from trajcache_client._operations import Operation

T = TypeVar("T")


class IkMethods:
    """Methods of the blocking client over `call`."""

    def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    def ik(self, robot_id: str, request: Mapping[str, Any]) -> IkResult:
        """Inverse kinematics: `{link, position, orientation, seed, ...}` → the state nearest the
        seed that puts the link at the pose (in the robot's current scene)."""
        return self.call(ops.ik(robot_id, request))

    def get_position_ik(
        self, robot_id: str, request: Mapping[str, Any] | str
    ) -> GetPositionIKResponse:
        """Inverse kinematics with MoveIt's GetPositionIK request (a mapping as JSON, text as
        YAML) → its response, whose `error_code` says whether it succeeded (-31: no solution)."""
        return self.call(ops.get_position_ik(robot_id, request))


class AsyncIkMethods:
    """Methods of the asynchronous client over `call`."""

    async def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    async def ik(self, robot_id: str, request: Mapping[str, Any]) -> IkResult:
        """Inverse kinematics: `{link, position, orientation, seed, ...}` → the state nearest the
        seed that puts the link at the pose (in the robot's current scene)."""
        return await self.call(ops.ik(robot_id, request))

    async def get_position_ik(
        self, robot_id: str, request: Mapping[str, Any] | str
    ) -> GetPositionIKResponse:
        """Inverse kinematics with MoveIt's GetPositionIK request (a mapping as JSON, text as
        YAML) → its response, whose `error_code` says whether it succeeded (-31: no solution)."""
        return await self.call(ops.get_position_ik(robot_id, request))
