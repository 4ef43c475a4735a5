"""The 3D view's methods of `Client` and `AsyncClient` (each a one-line call of its operation)."""

from __future__ import annotations

from typing import TypeVar

from trajcache_client import _view_operations as ops
from trajcache_client._operations import Operation
from trajcache_client._view_models import ModelView, PathView, StoredScene

T = TypeVar("T")


class ViewMethods:
    """Methods of the blocking client over `call`."""

    def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    def get_model_file(self, model_id: str, path: str) -> bytes:
        """A file of a model's archive (a mesh), byte for byte as uploaded."""
        return self.call(ops.get_model_file(model_id, path))

    def get_scene_version(self, robot_id: str, version: int) -> StoredScene:
        """Any stored version of a robot's scene."""
        return self.call(ops.get_scene_version(robot_id, version))

    def get_scene_by_hash(self, scene_hash: str) -> StoredScene:
        """The stored scene with this content hash (a trajectory's or a plan event's)."""
        return self.call(ops.get_scene_by_hash(scene_hash))

    def model_view(self, model_id: str) -> ModelView:
        """A model's links and collision geometry, as the 3D view draws them."""
        return self.call(ops.model_view(model_id))

    def model_mesh(self, model_id: str, element: int) -> bytes:
        """A mesh element's triangles as the validator checks them, as binary STL."""
        return self.call(ops.model_mesh(model_id, element))

    def trajectory_view(self, trajectory_id: int, *, scene_hash: str | None = None) -> PathView:
        """A stored trajectory as link poses at its validation samples, in its scene."""
        return self.call(ops.trajectory_view(trajectory_id, scene_hash=scene_hash))

    def plan_event_view(self, event_id: int, *, candidate: int | None = None) -> PathView:
        """What a plan request validated: a rejected candidate at its first failing sample."""
        return self.call(ops.plan_event_view(event_id, candidate=candidate))


class AsyncViewMethods:
    """Methods of the asyncio client over `call`."""

    async def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError

    async def get_model_file(self, model_id: str, path: str) -> bytes:
        """A file of a model's archive (a mesh), byte for byte as uploaded."""
        return await self.call(ops.get_model_file(model_id, path))

    async def get_scene_version(self, robot_id: str, version: int) -> StoredScene:
        """Any stored version of a robot's scene."""
        return await self.call(ops.get_scene_version(robot_id, version))

    async def get_scene_by_hash(self, scene_hash: str) -> StoredScene:
        """The stored scene with this content hash (a trajectory's or a plan event's)."""
        return await self.call(ops.get_scene_by_hash(scene_hash))

    async def model_view(self, model_id: str) -> ModelView:
        """A model's links and collision geometry, as the 3D view draws them."""
        return await self.call(ops.model_view(model_id))

    async def model_mesh(self, model_id: str, element: int) -> bytes:
        """A mesh element's triangles as the validator checks them, as binary STL."""
        return await self.call(ops.model_mesh(model_id, element))

    async def trajectory_view(
        self, trajectory_id: int, *, scene_hash: str | None = None
    ) -> PathView:
        """A stored trajectory as link poses at its validation samples, in its scene."""
        return await self.call(ops.trajectory_view(trajectory_id, scene_hash=scene_hash))

    async def plan_event_view(self, event_id: int, *, candidate: int | None = None) -> PathView:
        """What a plan request validated: a rejected candidate at its first failing sample."""
        return await self.call(ops.plan_event_view(event_id, candidate=candidate))
