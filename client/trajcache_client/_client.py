"""The blocking client."""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

import httpx

from trajcache_client import _admin_operations as admin_ops
from trajcache_client import _operations as ops
from trajcache_client._admin_client import AdminMethods
from trajcache_client._base import DEFAULT_BASE_URL, DEFAULT_RETRY, DEFAULT_TIMEOUT, BaseClient
from trajcache_client._exceptions import error_for
from trajcache_client._ik_client import IkMethods
from trajcache_client._models import (
    Health,
    Page,
    PlanOptions,
    PlanResult,
    Robot,
    RobotKind,
    RobotModel,
    RobotModelDetail,
    RobotModelSummary,
    Scene,
    SceneVersion,
    Trajectory,
    TrajectoryCreated,
    TrajectorySummary,
)
from trajcache_client._moveit_models import MotionPlanResponse
from trajcache_client._operations import JointLimits, Operation, StateLike, StateValues
from trajcache_client._retry import Retry
from trajcache_client._view_client import ViewMethods

T = TypeVar("T")


class Client(AdminMethods, ViewMethods, IkMethods, BaseClient):
    """A blocking trajcache client; use it as a context manager or call `close()`.

    `transport` replaces the network, e.g. `httpx.MockTransport(handler)` in tests.
    """

    def __init__(
        self,
        base_url: str = DEFAULT_BASE_URL,
        *,
        api_key: str | None = None,
        headers: Mapping[str, str] | None = None,
        timeout: float | httpx.Timeout | None = DEFAULT_TIMEOUT,
        retry: Retry = DEFAULT_RETRY,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        super().__init__(base_url, api_key=api_key, headers=headers, timeout=timeout, retry=retry)
        self._http = httpx.Client(transport=transport, **self._http_options())

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the connections."""
        self._http.close()

    def call(self, op: Operation[T]) -> T:
        """Send `op`, retrying as the policy allows, and return its answer or raise."""
        return self._result(op, self._send(op))

    def _send(self, op: Operation[Any], *, stream: bool = False) -> httpx.Response:
        """The answer to `op` once the retry policy lets it stand (streamed: still unread)."""
        retry = 0
        while True:
            try:
                response = self._http.send(self._request(self._http, op), stream=stream)
            except httpx.TransportError as exc:
                wait = self._wait_after_error(op, retry, exc)
                if wait is None:
                    raise self._transport_error(op, exc) from exc
            else:
                wait = self._wait_after_answer(op, retry, response)
                if wait is None:
                    return response
                response.close()
            time.sleep(wait)
            retry += 1

    def iter_export_cache(
        self,
        *,
        model_ids: Iterable[str] = (),
        sources: Iterable[str] = (),
        newer_than_s: float | None = None,
        older_than_s: float | None = None,
        models: bool = True,
        chunk_size: int | None = None,
    ) -> Iterator[bytes]:
        """The cache as JSON Lines, chunk by chunk as it arrives (sent on the first read)."""
        op = admin_ops.export_cache(
            model_ids=model_ids,
            sources=sources,
            newer_than_s=newer_than_s,
            older_than_s=older_than_s,
            models=models,
        )
        response = self._send(op, stream=True)
        try:
            if not response.is_success:
                response.read()
                raise error_for(response)
            yield from response.iter_bytes(chunk_size)
        except httpx.TransportError as exc:
            raise self._transport_error(op, exc) from exc
        finally:
            response.close()

    # --- robot models -----------------------------------------------------------------------

    def register_model(
        self,
        urdf: str,
        *,
        srdf: str | None = None,
        group: str | None = None,
        joint_values: Mapping[str, float] | str | None = None,
        base: str = "fixed",
        joint_names: Sequence[str] | None = None,
        name: str | None = None,
        archive: bytes | Path | None = None,
        archive_name: str = "meshes.zip",
        acceleration_limits: JointLimits | None = None,
        jerk_limits: JointLimits | None = None,
        end_effector_link: str | None = None,
    ) -> RobotModel:
        """Register a URDF (with its SRDF and a zip or tar(.gz) mesh archive); same content →
        same model_id. `joint_values` holds joints outside the planning joints (by name, or an
        SRDF group_state's name)."""
        return self.call(
            ops.register_model(
                urdf,
                srdf=srdf,
                group=group,
                joint_values=joint_values,
                base=base,
                joint_names=joint_names,
                name=name,
                archive=archive,
                archive_name=archive_name,
                acceleration_limits=acceleration_limits,
                jerk_limits=jerk_limits,
                end_effector_link=end_effector_link,
            )
        )

    def list_models(self, *, limit: int | None = None, offset: int = 0) -> Page[RobotModelSummary]:
        """A page of registered models, oldest first."""
        return self.call(ops.list_models(limit=limit, offset=offset))

    def get_model(self, model_id: str) -> RobotModelDetail:
        """A model with its joints, links, limits and files."""
        return self.call(ops.get_model(model_id))

    # --- robots and scenes ------------------------------------------------------------------

    def put_robot(
        self,
        robot_id: str,
        model_id: str,
        *,
        kind: RobotKind | None = None,
        joint_values: Mapping[str, float] | None = None,
    ) -> Robot:
        """Create a robot, or re-point it to another model; `joint_values` holds joints
        otherwise than the model. None keeps what the robot has; `joint_values={}` returns to
        the model's values."""
        return self.call(ops.put_robot(robot_id, model_id, kind=kind, joint_values=joint_values))

    def get_robot(self, robot_id: str) -> Robot:
        """A robot."""
        return self.call(ops.get_robot(robot_id))

    def put_scene(
        self,
        robot_id: str,
        scene: Mapping[str, Any] | str | bytes,
        *,
        media_type: str | None = None,
    ) -> SceneVersion:
        """Replace the scene: a mapping (native or MoveIt world) as JSON, text as YAML."""
        return self.call(ops.put_scene(robot_id, scene, media_type=media_type))

    def patch_scene(
        self,
        robot_id: str,
        *,
        upsert: Sequence[Mapping[str, Any]] = (),
        remove: Sequence[str] = (),
        env: Mapping[str, float | None] | None = None,
    ) -> SceneVersion:
        """Add or replace objects by id, remove ids, set env values (None removes one)."""
        return self.call(ops.patch_scene(robot_id, upsert=upsert, remove=remove, env=env))

    def get_scene(self, robot_id: str) -> Scene:
        """The robot's current scene, its version and hash."""
        return self.call(ops.get_scene(robot_id))

    # --- planning ---------------------------------------------------------------------------

    def plan(
        self,
        robot_id: str,
        start: StateLike,
        goal: StateLike | None,
        options: PlanOptions | Mapping[str, Any] | None = None,
        *,
        goal_pose: Mapping[str, Any] | None = None,
    ) -> PlanResult:
        """A validated trajectory from start to goal, from the cache or the planner; each state
        is values in `state_names` order, a {joint: value} map, or a named state's name."""
        return self.call(ops.plan(robot_id, start, goal, options, goal_pose=goal_pose))

    def motion_plan(self, robot_id: str, request: Mapping[str, Any] | str) -> MotionPlanResponse:
        """Plan with MoveIt's messages: a MotionPlanRequest (a mapping as JSON, text as YAML) →
        its MotionPlanResponse, whose `error_code` says whether it succeeded."""
        return self.call(ops.motion_plan(robot_id, request))

    # --- trajectories -----------------------------------------------------------------------

    def store_trajectory(
        self,
        model_id: str,
        states: Iterable[StateValues],
        *,
        source: str = "real",
        robot_id: str | None = None,
        scene_hash: str | None = None,
        env: Mapping[str, float] | None = None,
        planning_time_ms: float | None = None,
    ) -> TrajectoryCreated:
        """Contribute a trajectory; an identical one is not stored twice."""
        return self.call(
            ops.store_trajectory(
                model_id,
                states,
                source=source,
                robot_id=robot_id,
                scene_hash=scene_hash,
                env=env,
                planning_time_ms=planning_time_ms,
            )
        )

    def list_trajectories(
        self,
        *,
        model_id: str | None = None,
        source: str | None = None,
        robot_id: str | None = None,
        limit: int | None = None,
        offset: int = 0,
    ) -> Page[TrajectorySummary]:
        """A page of stored trajectories (without states), filtered."""
        return self.call(
            ops.list_trajectories(
                model_id=model_id, source=source, robot_id=robot_id, limit=limit, offset=offset
            )
        )

    def get_trajectory(self, trajectory_id: int) -> Trajectory:
        """A stored trajectory with its key states."""
        return self.call(ops.get_trajectory(trajectory_id))

    def delete_trajectory(self, trajectory_id: int) -> None:
        """Delete a stored trajectory."""
        self.call(ops.delete_trajectory(trajectory_id))

    # --- health -----------------------------------------------------------------------------

    def health(self) -> Health:
        """Liveness: the service process answers."""
        return self.call(ops.health())

    def ready(self) -> Health:
        """Readiness: the database answers (UnavailableError otherwise)."""
        return self.call(ops.ready())
