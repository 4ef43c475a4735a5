"""Robot models: registration (idempotent by content hash) and a per-process cache of them."""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import defusedxml.ElementTree as DefusedET
import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, defer

from trajcache.db import models as tables
from trajcache.db.sources import read_model_source, stored_files
from trajcache.geometry.errors import RobotModelError
from trajcache.geometry.model.files import MeshResolver, unpack_archive
from trajcache.geometry.model.robot import BASE_STATE_NAMES, BaseType, RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.planning.problem import ModelSource
from trajcache.services.catalog.model_config import (
    JointLimits,
    ModelConfig,
    check_same_config,
    joint_limits,
    link_name,
)
from trajcache.services.errors import NotFoundError, PayloadTooLargeError

NAME_MAX = 200  # robot_models.name column width


class ModelRegistry:
    """Thread-safe in-memory cache of loaded geometry models by model id."""

    def __init__(self) -> None:
        self._models: dict[str, RobotModel] = {}
        self._sources: dict[str, ModelSource] = {}
        self._lock = threading.Lock()

    def get(self, model_id: str) -> RobotModel | None:
        """The cached model, or None."""
        with self._lock:
            return self._models.get(model_id)

    def put(self, model: RobotModel) -> RobotModel:
        """Cache `model`; when another thread cached it first, return that one."""
        with self._lock:
            return self._models.setdefault(model.model_id, model)

    def get_source(self, model_id: str) -> ModelSource | None:
        """The cached worker-side description of a model, or None."""
        with self._lock:
            return self._sources.get(model_id)

    def put_source(self, source: ModelSource) -> ModelSource:
        """Cache a model's worker-side description and return the cached one."""
        with self._lock:
            return self._sources.setdefault(source.model_id, source)

    def clear(self) -> None:
        """Forget every model and source."""
        with self._lock:
            self._models.clear()
            self._sources.clear()

    def __contains__(self, model_id: object) -> bool:
        with self._lock:
            return model_id in self._models

    def __len__(self) -> int:
        with self._lock:
            return len(self._models)


@dataclass(frozen=True)
class ModelFileInfo:
    """A stored file of a model, without its content."""

    path: str
    sha256: str
    size: int


def state_names(base: str, joint_names: Sequence[str]) -> list[str]:
    """Names of the state values of a model with this base and these planning joints."""
    prefix = list(BASE_STATE_NAMES) if base == BaseType.PLANAR.value else []
    return prefix + list(joint_names)


def unpack_model_archive(data: bytes, *, max_bytes: int, max_entries: int) -> dict[str, bytes]:
    """Files of an uploaded mesh archive; PayloadTooLargeError above `max_bytes`."""
    if len(data) > max_bytes:
        raise PayloadTooLargeError(
            f"mesh archive has {len(data)} bytes, more than max_archive_bytes={max_bytes}"
        )
    return unpack_archive(data, max_entries=max_entries, max_total_bytes=max_bytes)


def referenced_files(urdf: str, files: Mapping[str, bytes]) -> dict[str, bytes]:
    """The uploaded files that the URDF's collision meshes resolve to (call after loading it)."""
    if not files:
        return {}
    resolver = MeshResolver(files)
    root = DefusedET.fromstring(urdf.strip(), forbid_dtd=True)
    out: dict[str, bytes] = {}
    for mesh in root.iterfind("./link/collision/geometry/mesh"):
        path = resolver.resolve(mesh.get("filename", ""))
        out[path] = resolver.files[path]
    return out


def _model_config(
    model: RobotModel,
    acceleration_limits: JointLimits | None,
    jerk_limits: JointLimits | None,
    end_effector_link: str | None,
) -> ModelConfig:
    """The configuration given at registration, checked against the model's joints and links."""
    return ModelConfig(
        acceleration_limits=joint_limits(model, acceleration_limits, "acceleration_limits"),
        jerk_limits=joint_limits(model, jerk_limits, "jerk_limits"),
        end_effector_link=link_name(model, end_effector_link),
    )


@dataclass(frozen=True)
class ModelRegistration:
    """What registers a model: its URDF, files and semantics, and its configuration.

    The SRDF, when given, chooses the planning joints (`group`), names states and disables
    self-collision pairs; `joint_values` holds joints outside the planning joints (by name, or
    an SRDF group_state's name). Both are part of the model id. Acceleration and jerk limits
    (one value for every planning joint, or per joint name) and the end-effector link are the
    model's configuration, fixed at its first registration.
    """

    urdf: str
    files: Mapping[str, bytes] | None = None
    base: BaseType | str = BaseType.FIXED
    joint_names: Sequence[str] | None = None
    group: str | None = None
    srdf: str | None = None
    joint_values: Mapping[str, float] | str | None = None
    name: str | None = None
    acceleration_limits: JointLimits | None = None
    jerk_limits: JointLimits | None = None
    end_effector_link: str | None = None


def register_model(
    *,
    session: Session,
    registry: ModelRegistry,
    registration: ModelRegistration,
    max_urdf_bytes: int | None = None,
    commit: bool = True,
) -> tuple[RobotModel, bool]:
    """Register a model (same content → same model id, no new rows); return it and `created`.

    Registering the same content again with a different configuration is a ConflictError.
    With `commit=False` a new model's row is only flushed and not put in `registry`: the caller
    commits it with its other writes, then caches the model.
    """
    r = registration
    urdf, srdf, files = r.urdf, r.srdf, r.files or {}
    _check_size("URDF", urdf, max_urdf_bytes)
    _check_size("SRDF", srdf, max_urdf_bytes)
    model = load_robot_model(
        urdf,
        files=files,
        base=r.base,
        joint_names=r.joint_names,
        group=r.group,
        srdf=srdf,
        joint_values=r.joint_values,
        name=r.name,
    )
    check_plannable(model)
    model = replace(model, name=model.name[:NAME_MAX])
    config = _model_config(model, r.acceleration_limits, r.jerk_limits, r.end_effector_link)
    existing = _stored(session, model.model_id)
    if existing is not None:
        stored_name, stored = existing
        check_same_config(model.model_id, stored, config)
        return _cached(registry, model, stored_name, stored), False
    row = _model_row(
        model, config, urdf=urdf, files=files, semantics=_semantics(srdf, r.joint_values)
    )
    if not commit:  # a concurrent registration fails the caller's transaction on IntegrityError
        session.add(row)
        session.flush()
        return config.apply(model), True
    return _insert_model(session=session, registry=registry, model=model, config=config, row=row)


def check_plannable(model: RobotModel) -> None:
    """RobotModelError (a 422) when the model has nothing to plan: no joint and a fixed base."""
    if model.dof > 0:
        return
    held = sorted(model.held_values)
    why = f"every movable joint is held ({held})" if held else "its URDF has only fixed joints"
    raise RobotModelError(
        f"the model has nothing to plan: {why} and its base is fixed "
        "(register a mobile base with base 'planar')"
    )


def _check_size(what: str, text: str | None, max_bytes: int | None) -> None:
    """PayloadTooLargeError when the URDF or SRDF `text` is over `max_bytes` (UTF-8)."""
    size = len(text.encode("utf-8")) if text is not None else 0
    if max_bytes is not None and size > max_bytes:
        raise PayloadTooLargeError(f"{what} has {size} bytes, more than max_urdf_bytes={max_bytes}")


def _model_row(
    model: RobotModel,
    config: ModelConfig,
    *,
    urdf: str,
    files: Mapping[str, bytes],
    semantics: dict[str, Any],
) -> tables.RobotModel:
    """The new row of a model, with the uploaded files its URDF references."""
    row = tables.RobotModel(
        id=model.model_id,
        name=model.name,
        base=model.base.value,
        joint_names=list(model.joint_names),
        urdf=urdf,
        allowed_pairs=[list(pair) for pair in sorted(model.allowed_pairs)],
        config=semantics,
        acceleration_limits=config.acceleration_limits,
        jerk_limits=config.jerk_limits,
        end_effector_link=config.end_effector_link,
    )
    row.files = [
        tables.ModelFile(path=path, sha256=hashlib.sha256(data).hexdigest(), data=data)
        for path, data in sorted(referenced_files(urdf, files).items())
    ]
    return row


def _insert_model(
    *,
    session: Session,
    registry: ModelRegistry,
    model: RobotModel,
    config: ModelConfig,
    row: tables.RobotModel,
) -> tuple[RobotModel, bool]:
    """Store a new model's row; one registered meanwhile elsewhere is returned instead."""
    session.add(row)
    try:
        session.commit()
    except IntegrityError:  # registered concurrently by another request or replica
        session.rollback()
        found = _stored(session, model.model_id)
        if found is None:
            raise
        check_same_config(model.model_id, found[1], config)
        return _cached(registry, model, *found), False
    return registry.put(config.apply(model)), True


def _semantics(srdf: str | None, joint_values: Mapping[str, float] | str | None) -> dict[str, Any]:
    """What the `config` column keeps besides the URDF: the SRDF and the held joint values."""
    out: dict[str, Any] = {}
    if srdf is not None:
        out["srdf"] = srdf
    if joint_values is not None:
        out["joint_values"] = (
            joint_values
            if isinstance(joint_values, str)
            else {k: float(v) for k, v in joint_values.items()}
        )
    return out


def _cached(
    registry: ModelRegistry, model: RobotModel, stored_name: str, config: ModelConfig
) -> RobotModel:
    cached = registry.get(model.model_id)
    if cached is not None:
        return cached
    return registry.put(config.apply(replace(model, name=stored_name)))


def _stored(session: Session, model_id: str) -> tuple[str, ModelConfig] | None:
    """The stored name and configuration of a model, or None."""
    t = tables.RobotModel
    row = session.execute(
        sa.select(t.name, t.acceleration_limits, t.jerk_limits, t.end_effector_link).where(
            t.id == model_id
        )
    ).one_or_none()
    if row is None:
        return None
    return row.name, ModelConfig(row.acceleration_limits, row.jerk_limits, row.end_effector_link)


def get_model(*, session: Session, registry: ModelRegistry, model_id: str) -> RobotModel:
    """The geometry model `model_id`, loaded from the database on a cache miss."""
    cached = registry.get(model_id)
    if cached is not None:
        return cached
    row = session.get(tables.RobotModel, model_id)
    if row is None:
        raise NotFoundError(f"robot model {model_id!r} not found")
    semantics = row.config or {}
    model = load_robot_model(
        row.urdf,
        files=stored_files(session, model_id),
        base=row.base,
        joint_names=row.joint_names,
        srdf=semantics.get("srdf"),
        joint_values=semantics.get("joint_values"),
        name=row.name,
    )
    if model.model_id != row.id:  # hashing changed since registration: the stored id rules
        model = replace(model, model_id=row.id)
    config = ModelConfig(row.acceleration_limits, row.jerk_limits, row.end_effector_link)
    return registry.put(config.apply(model))


def model_source(
    *, session: Session, model_id: str, registry: ModelRegistry | None = None
) -> ModelSource:
    """What a planner worker needs to rebuild model `model_id` (picklable; cached if a registry
    is given)."""
    if registry is not None and (cached := registry.get_source(model_id)) is not None:
        return cached
    source = read_model_source(session, model_id)
    if source is None:
        raise NotFoundError(f"robot model {model_id!r} not found")
    return registry.put_source(source) if registry is not None else source


def get_model_row(*, session: Session, model_id: str) -> tables.RobotModel:
    """The stored row of model `model_id`."""
    row = session.scalar(
        sa.select(tables.RobotModel)
        .options(defer(tables.RobotModel.urdf, raiseload=True))
        .where(tables.RobotModel.id == model_id)
    )
    if row is None:
        raise NotFoundError(f"robot model {model_id!r} not found")
    return row


def list_model_files(*, session: Session, model_id: str) -> list[ModelFileInfo]:
    """Paths, hashes and sizes of a model's stored files."""
    rows = session.execute(
        sa.select(
            tables.ModelFile.path, tables.ModelFile.sha256, sa.func.length(tables.ModelFile.data)
        )
        .where(tables.ModelFile.model_id == model_id)
        .order_by(tables.ModelFile.path)
    )
    return [ModelFileInfo(path, sha, int(size or 0)) for path, sha, size in rows]


def list_models(
    *, session: Session, limit: int, offset: int = 0
) -> tuple[list[tables.RobotModel], int]:
    """A page of registered models (oldest first) and the total count."""
    total = session.execute(sa.select(sa.func.count()).select_from(tables.RobotModel)).scalar_one()
    rows = session.scalars(
        sa.select(tables.RobotModel)
        .options(defer(tables.RobotModel.urdf, raiseload=True))
        .order_by(tables.RobotModel.created_at, tables.RobotModel.id)
        .limit(limit)
        .offset(offset)
    ).all()
    return list(rows), int(total)
