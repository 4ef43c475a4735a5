"""Every endpoint declared once, as a method of both `Client` and `AsyncClient`.

An endpoint is its sans-IO operation (a function in `_operations`, `_admin_operations`,
`_view_operations` or `_ik_operations`) and the client's docstring for it. `Endpoint` turns that
pair into a method: on a blocking client it returns `client.call(op)`, on an asyncio client it
is a coroutine function awaiting `client.call(op)`. Its parameters are the operation's (a
`ParamSpec`), so a type checker sees each method's full signature, and `inspect.signature` and
`help()` show it too. Adding an endpoint is a function in an `_operations` module and one line
in `Endpoints`.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Coroutine
from typing import Any, Generic, ParamSpec, TypeVar, overload

from trajcache_client import _admin_operations as admin_ops
from trajcache_client import _ik_operations as ik_ops
from trajcache_client import _operations as ops
from trajcache_client import _view_operations as view_ops
from trajcache_client._operations import Operation

P = ParamSpec("P")
T = TypeVar("T")


class SyncCaller:
    """A client whose `call` blocks until the answer (`Client`)."""

    def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError


class AsyncCaller:
    """A client whose `call` is a coroutine (`AsyncClient`)."""

    async def call(self, op: Operation[T]) -> T:
        """Send `op` and return its answer (the client's own `call`)."""
        raise NotImplementedError


class Endpoint(Generic[P, T]):
    """A method of both clients made from one operation: `build` makes the request, `call` sends."""

    def __init__(self, build: Callable[P, Operation[T]], doc: str) -> None:
        self.build = build
        self.__doc__ = doc
        self._sync = self._method(build, doc, asynchronous=False)
        self._async = self._method(build, doc, asynchronous=True)

    @staticmethod
    def _method(
        build: Callable[P, Operation[T]], doc: str, *, asynchronous: bool
    ) -> Callable[..., Any]:
        def sync_method(client: SyncCaller, /, *args: P.args, **kwargs: P.kwargs) -> T:
            return client.call(build(*args, **kwargs))

        async def async_method(client: AsyncCaller, /, *args: P.args, **kwargs: P.kwargs) -> T:
            return await client.call(build(*args, **kwargs))

        method: Callable[..., Any] = async_method if asynchronous else sync_method
        method.__name__ = method.__qualname__ = build.__name__
        method.__doc__ = doc
        signature = inspect.signature(build)
        self_parameter = inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)
        answer = signature.return_annotation  # "Operation[X]": the method returns X
        if isinstance(answer, str) and answer.startswith("Operation[") and answer.endswith("]"):
            answer = answer[len("Operation[") : -1]
        method.__signature__ = signature.replace(  # type: ignore[attr-defined]
            parameters=[self_parameter, *signature.parameters.values()], return_annotation=answer
        )
        return method

    @overload
    def __get__(self, client: None, owner: type[Any]) -> Callable[..., Any]: ...

    @overload
    def __get__(self, client: SyncCaller, owner: type[Any]) -> Callable[P, T]: ...

    @overload
    def __get__(
        self, client: AsyncCaller, owner: type[Any]
    ) -> Callable[P, Coroutine[Any, Any, T]]: ...

    def __get__(self, client: object, owner: type[Any]) -> Callable[..., Any]:
        asynchronous = inspect.iscoroutinefunction(getattr(owner, "call", None))
        method = self._async if asynchronous else self._sync
        return method if client is None else method.__get__(client, owner)


def endpoint(build: Callable[P, Operation[T]], doc: str) -> Endpoint[P, T]:
    """The method of both clients that sends `build`'s operation, documented by `doc`."""
    return Endpoint(build, doc)


class Endpoints:
    """The endpoints' methods, shared by `Client` and `AsyncClient`."""

    # --- robot models -----------------------------------------------------------------------
    register_model = endpoint(
        ops.register_model,
        """Register a URDF (with its SRDF and a zip or tar(.gz) mesh archive); same content →
        same model_id. `joint_values` holds joints outside the planning joints (by name, or an
        SRDF group_state's name).""",
    )
    list_models = endpoint(ops.list_models, "A page of registered models, oldest first.")
    get_model = endpoint(ops.get_model, "A model with its joints, links, limits and files.")

    # --- robots and scenes ------------------------------------------------------------------
    put_robot = endpoint(
        ops.put_robot,
        """Create a robot, or re-point it to another model; `joint_values` holds joints
        otherwise than the model. None keeps what the robot has; `joint_values={}` returns to
        the model's values.""",
    )
    get_robot = endpoint(ops.get_robot, "A robot.")
    put_scene = endpoint(
        ops.put_scene,
        "Replace the scene: a mapping (native or MoveIt world) as JSON, text as YAML.",
    )
    patch_scene = endpoint(
        ops.patch_scene,
        "Add or replace objects by id, remove ids, set env values (None removes one).",
    )
    get_scene = endpoint(ops.get_scene, "The robot's current scene, its version and hash.")

    # --- planning and inverse kinematics ----------------------------------------------------
    plan = endpoint(
        ops.plan,
        """A validated trajectory from start to goal, from the cache or the planner; each state
        is values in `state_names` order, a {joint: value} map, or a named state's name.""",
    )
    motion_plan = endpoint(
        ops.motion_plan,
        """Plan with MoveIt's messages: a MotionPlanRequest (a mapping as JSON, text as YAML) →
        its MotionPlanResponse, whose `error_code` says whether it succeeded.""",
    )
    ik = endpoint(
        ik_ops.ik,
        """Inverse kinematics: `{link, position, orientation, seed, ...}` → the state nearest the
        seed that puts the link at the pose (in the robot's current scene).""",
    )
    get_position_ik = endpoint(
        ik_ops.get_position_ik,
        """Inverse kinematics with MoveIt's GetPositionIK request (a mapping as JSON, text as
        YAML) → its response, whose `error_code` says whether it succeeded (-31: no solution).""",
    )
    cartesian_path = endpoint(
        ik_ops.cartesian_path,
        """A Cartesian path: `{start, link, waypoints, max_step, ...}` → the joint path moving
        the link along straight lines, as far as it goes, certified in the robot's scene.""",
    )
    get_cartesian_path = endpoint(
        ik_ops.get_cartesian_path,
        """A Cartesian path with MoveIt's GetCartesianPath request (a mapping as JSON, text as
        YAML) → its response: `fraction`, and `error_code` 1 whatever the fraction.""",
    )

    # --- trajectories -----------------------------------------------------------------------
    store_trajectory = endpoint(
        ops.store_trajectory, "Contribute a trajectory; an identical one is not stored twice."
    )
    list_trajectories = endpoint(
        ops.list_trajectories, "A page of stored trajectories (without states), filtered."
    )
    get_trajectory = endpoint(ops.get_trajectory, "A stored trajectory with its key states.")
    delete_trajectory = endpoint(ops.delete_trajectory, "Delete a stored trajectory.")

    # --- health -----------------------------------------------------------------------------
    health = endpoint(ops.health, "Liveness: the service process answers.")
    ready = endpoint(ops.ready, "Readiness: the database answers (UnavailableError otherwise).")

    # --- seed jobs --------------------------------------------------------------------------
    create_seed_job = endpoint(
        admin_ops.create_seed_job,
        "Queue a seed job (the `POST /v1/seed-jobs` body); `model_id` fills in its model.",
    )
    list_seed_jobs = endpoint(admin_ops.list_seed_jobs, "A page of seed jobs, newest first.")
    get_seed_job = endpoint(admin_ops.get_seed_job, "A seed job's state and progress.")
    cancel_seed_job = endpoint(
        admin_ops.cancel_seed_job,
        "Cancel a queued or running seed job (ConflictError when it already ended).",
    )

    # --- statistics and plan events ---------------------------------------------------------
    stats = endpoint(
        admin_ops.stats,
        """Hit rate, planner calls, time per step and time saved over a window ("24h"), of
        robots' and seed jobs' requests (`requester`: only theirs).""",
    )
    top_trajectories = endpoint(
        admin_ops.top_trajectories, "The most reused trajectories, by hits."
    )
    plan_events = endpoint(
        admin_ops.plan_events,
        "A page of plan events, newest first; pass `next_cursor` as `cursor` to go on.",
    )

    # --- admin ------------------------------------------------------------------------------
    prune = endpoint(
        admin_ops.prune,
        "Evict trajectories beyond the per-model cap (with `dry_run`, only list them).",
    )
    export_cache = endpoint(
        admin_ops.export_cache, "The cache as JSON Lines, whole (`iter_export_cache` streams it)."
    )
    import_cache = endpoint(
        admin_ops.import_cache,
        "Import an export (JSON Lines or their gzip; a Path is read); `source` relabels.",
    )

    # --- the 3D view ------------------------------------------------------------------------
    get_model_file = endpoint(
        view_ops.get_model_file,
        "A file of a model's archive (a mesh), byte for byte as uploaded.",
    )
    get_scene_version = endpoint(
        view_ops.get_scene_version, "Any stored version of a robot's scene."
    )
    get_scene_by_hash = endpoint(
        view_ops.get_scene_by_hash,
        "The stored scene with this content hash (a trajectory's or a plan event's).",
    )
    model_view = endpoint(
        view_ops.model_view, "A model's links and collision geometry, as the 3D view draws them."
    )
    model_mesh = endpoint(
        view_ops.model_mesh,
        "A mesh element's triangles as the validator checks them, as binary STL.",
    )
    trajectory_view = endpoint(
        view_ops.trajectory_view,
        "A stored trajectory as link poses at its validation samples, in its scene.",
    )
    cartesian_path_view = endpoint(
        view_ops.cartesian_path_view,
        "A stored Cartesian path as link poses, with the straight lines it follows.",
    )
    plan_event_view = endpoint(
        view_ops.plan_event_view,
        "What a plan request validated: a rejected candidate at its first failing sample.",
    )
