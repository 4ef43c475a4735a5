"""The IK and Cartesian path methods of `Client` and `AsyncClient` (each a one-line call of
its operation)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from trajcache_client import _ik_operations as ops
from trajcache_client._models import CartesianResult, IkResult
from trajcache_client._moveit_models import GetCartesianPathResponse, GetPositionIKResponse
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

    def cartesian_path(self, robot_id: str, request: Mapping[str, Any]) -> CartesianResult:
        """A Cartesian path: `{start, link, waypoints, max_step, ...}` → the joint path moving
        the link along straight lines, as far as it goes, certified in the robot's scene."""
        return self.call(ops.cartesian_path(robot_id, request))

    def get_cartesian_path(
        self, robot_id: str, request: Mapping[str, Any] | str
    ) -> GetCartesianPathResponse:
        """A Cartesian path with MoveIt's GetCartesianPath request (a mapping as JSON, text as
        YAML) → its response: `fraction`, and `error_code` 1 whatever the fraction."""
        return self.call(ops.get_cartesian_path(robot_id, request))


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

    async def cartesian_path(self, robot_id: str, request: Mapping[str, Any]) -> CartesianResult:
        """A Cartesian path: `{start, link, waypoints, max_step, ...}` → the joint path moving
        the link along straight lines, as far as it goes, certified in the robot's scene."""
        return await self.call(ops.cartesian_path(robot_id, request))

    async def get_cartesian_path(
        self, robot_id: str, request: Mapping[str, Any] | str
    ) -> GetCartesianPathResponse:
        """A Cartesian path with MoveIt's GetCartesianPath request (a mapping as JSON, text as
        YAML) → its response: `fraction`, and `error_code` 1 whatever the fraction."""
        return await self.call(ops.get_cartesian_path(robot_id, request))
