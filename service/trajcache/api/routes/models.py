"""/v1/robot-models: register (JSON or multipart/form-data), list and read robot models."""

from __future__ import annotations

import base64
import binascii
import json
import math
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError
from starlette.datastructures import UploadFile
from starlette.exceptions import HTTPException

from trajcache.api.bounded import (
    BoundedBodyRoute,
    is_json_media,
    media_type,
    unsupported_media,
)
from trajcache.api.deps import CtxDep, PageDep, SessionDep, SettingsDep
from trajcache.api.responses import COMMON, errors
from trajcache.api.schemas.models import (
    URDF_EXAMPLE,
    ModelFileOut,
    RobotModelDetail,
    RobotModelIn,
    RobotModelOut,
    RobotModelPage,
    RobotModelSummary,
    SkippedPairOut,
    check_form_field,
)
from trajcache.core.config import Settings
from trajcache.geometry.collision.shared import GeometryCache
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.path_quality import end_effector_link
from trajcache.services.catalog.models import (
    ModelRegistration,
    get_model,
    get_model_row,
    list_model_files,
    list_models,
    register_model,
    state_names,
    unpack_model_archive,
)
from trajcache.services.errors import InvalidInputError, PayloadTooLargeError
from trajcache.timing import kinematic_limits


def registration_body_limit(settings: Settings) -> tuple[int, str]:
    """A registration carries a URDF and a mesh archive (base64 in JSON): their limits bound it."""
    limit = settings.max_urdf_bytes + math.ceil(settings.max_archive_bytes * 4 / 3) + 65536
    return limit, (
        f"max_urdf_bytes={settings.max_urdf_bytes} plus "
        f"max_archive_bytes={settings.max_archive_bytes} allow"
    )


class RegistrationRoute(BoundedBodyRoute):
    """Bodies bounded by the URDF and archive limits (a mesh archive may pass max_body_bytes)."""

    limit_fn = staticmethod(registration_body_limit)


router = APIRouter(
    prefix="/robot-models",
    tags=["robot models"],
    responses=COMMON,
    route_class=RegistrationRoute,
)

_FORM_SCHEMA = {
    "type": "object",
    "required": ["urdf"],
    "properties": {
        "urdf": {"type": "string", "description": "URDF text (a field or an uploaded file)."},
        "srdf": {"type": "string", "description": "SRDF text (a field or an uploaded file)."},
        "group": {"type": "string", "description": "SRDF planning group."},
        "joint_values": {
            "type": "string",
            "description": "Held joint values: a JSON object by joint name, or a group_state name.",
        },
        "base": {"type": "string", "enum": ["fixed", "planar"], "default": "fixed"},
        "joint_names": {"type": "string", "description": "Comma-separated planning joints."},
        "name": {"type": "string"},
        "acceleration_limits": {"type": "string", "description": "A number or JSON object."},
        "jerk_limits": {"type": "string", "description": "A number or JSON object."},
        "end_effector_link": {"type": "string"},
        "archive": {"type": "string", "format": "binary", "description": "zip or tar(.gz)."},
    },
}
_REGISTRATION_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": RobotModelIn.model_json_schema()},
            "multipart/form-data": {
                "schema": _FORM_SCHEMA,
                "example": {"urdf": URDF_EXAMPLE, "base": "planar", "archive": "(meshes.zip)"},
            },
        },
    }
}


@dataclass(frozen=True)
class Registration:
    """A parsed registration request: the fields and the raw mesh archive, if any."""

    fields: RobotModelIn
    archive: bytes | None


def _reject_constant(token: str) -> Any:
    raise ValueError(f"{token} is not a valid JSON value")


def _validated(data: Any) -> RobotModelIn:
    try:
        return RobotModelIn.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False, include_input=False)
        raise RequestValidationError([{**e, "loc": ("body", *e["loc"])} for e in errors]) from None


def _from_json(body: bytes, settings: Settings) -> Registration:
    # The body's size is bounded while it is read (RegistrationRoute).
    try:
        data = json.loads(body, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as exc:
        raise RequestValidationError(
            [{"type": "json_invalid", "loc": ("body",), "msg": f"invalid JSON: {exc}"}]
        ) from None
    fields = _validated(data)
    archive = None
    if fields.archive_base64 is not None:
        encoded = fields.archive_base64
        if len(encoded) * 3 // 4 > settings.max_archive_bytes + 2:
            limit = settings.max_archive_bytes
            raise PayloadTooLargeError(
                f"archive_base64 decodes to more than max_archive_bytes={limit}"
            )
        try:
            archive = base64.b64decode(encoded, validate=True)
        except (binascii.Error, ValueError):
            raise InvalidInputError("body.archive_base64: not valid base64") from None
    return Registration(fields, archive)


async def _read_upload(upload: UploadFile, limit: int, what: str) -> bytes:
    data = await upload.read(limit + 1)
    if len(data) > limit:
        raise PayloadTooLargeError(f"{what} is larger than {limit} bytes")
    return data


async def _from_form(request: Request, settings: Settings) -> Registration:
    try:
        form = await request.form(max_files=3, max_fields=12, max_part_size=settings.max_urdf_bytes)
    except HTTPException as exc:
        if exc.status_code == 413:  # the whole body is too large (RegistrationRoute)
            raise
        if "size" in str(exc.detail).lower():
            raise PayloadTooLargeError(
                f"a form field exceeds max_urdf_bytes={settings.max_urdf_bytes}: {exc.detail}"
            ) from None
        raise InvalidInputError(f"malformed multipart body: {exc.detail}") from None
    try:
        data: dict[str, Any] = {}
        archive = None
        for key, value in form.multi_items():
            check_form_field(
                key, repeated=key in data or (key == "archive" and archive is not None)
            )
            if key == "archive":
                if not isinstance(value, UploadFile):
                    raise InvalidInputError("form field 'archive' must be an uploaded file")
                limit = settings.max_archive_bytes
                archive = await _read_upload(value, limit, f"archive (max_archive_bytes={limit})")
            elif isinstance(value, UploadFile):
                if key not in ("urdf", "srdf"):
                    raise InvalidInputError(f"form field {key!r} must not be a file")
                limit = settings.max_urdf_bytes
                what = key.upper()
                raw = await _read_upload(value, limit, f"{what} (max_urdf_bytes={limit})")
                try:
                    data[key] = raw.decode("utf-8-sig")
                except UnicodeDecodeError:
                    raise InvalidInputError(f"the uploaded {what} is not UTF-8 text") from None
            elif key == "joint_values":
                text = value.strip()
                if text.startswith("{"):
                    try:
                        data[key] = json.loads(text, parse_constant=_reject_constant)
                    except ValueError:
                        raise InvalidInputError(
                            "form field 'joint_values' is neither a JSON object nor a name"
                        ) from None
                else:
                    data[key] = text
            elif key in ("acceleration_limits", "jerk_limits"):
                try:  # one number, or a JSON object by joint name
                    data[key] = json.loads(value, parse_constant=_reject_constant)
                except ValueError:
                    raise InvalidInputError(
                        f"form field {key!r} must be a number or a JSON object"
                    ) from None
            elif key == "joint_names":
                names = [n.strip() for n in value.split(",") if n.strip()]
                data[key] = names or None
            else:
                data[key] = value
    finally:
        await form.close()
    return Registration(_validated(data), archive)


async def read_registration(request: Request, settings: SettingsDep) -> Registration:
    """Parse a registration sent as JSON or as a form (multipart, or URL-encoded without files)."""
    media = media_type(request)
    if media in ("multipart/form-data", "application/x-www-form-urlencoded"):
        return await _from_form(request, settings)
    if is_json_media(media):
        return _from_json(await request.body(), settings)
    raise unsupported_media(media, "application/json or multipart/form-data")


RegistrationDep = Annotated[Registration, Depends(read_registration)]


@router.post(
    "",
    status_code=201,
    response_model=RobotModelOut,
    summary="Register a robot model (same content → same model_id)",
    response_description="Registered: a new model",
    description="Registers a URDF with its base type (`fixed`, or `planar` for an x, y, θ mobile "
    "base) and planning joints (listed, an SRDF `group`, or every movable joint), optionally "
    "with its SRDF (disabled collision pairs, named states) and the values of joints held "
    "outside the planning joints. Every self-collision pair is checked except those listed in "
    "the answer's `skipped_pairs`, with the reason. Send JSON (mesh archive as "
    "`archive_base64`), or multipart/form-data with the URDF as a field or file and the meshes "
    "as an `archive` file (zip or tar(.gz)); `package://` and relative mesh URIs resolve inside "
    "the archive. The id is a hash of the content: registering the same content again answers "
    "200 with the same `model_id` and `created: false`.",
    openapi_extra=_REGISTRATION_BODY,
    responses={
        200: {"description": "Already registered: the same model_id", "model": RobotModelOut},
        **errors(
            {
                413: (
                    "URDF or archive above the size limits",
                    "URDF has 3145728 bytes, more than max_urdf_bytes=2097152",
                ),
                409: (
                    "Registered before with another timing or end-effector configuration",
                    "model 5158592d is already registered with acceleration_limits=2.0; a "
                    "model's configuration is fixed when it is first registered (asked for 3.0)",
                ),
                415: (
                    "Neither JSON nor multipart/form-data",
                    "unsupported content type 'text/xml'; send application/json or "
                    "multipart/form-data",
                ),
                422: (
                    "Unusable URDF, joints, meshes or archive",
                    "unknown joint names ['j9']; movable joints are ['j1']",
                ),
            }
        ),
    },
)
def register_model_route(
    registration: RegistrationDep, ctx: CtxDep, session: SessionDep, response: Response
) -> RobotModelOut:
    """Register a URDF with its mesh archive; 201 when new, 200 when it already existed."""
    s = ctx.settings
    fields = registration.fields
    files: dict[str, bytes] = {}
    if registration.archive is not None:
        files = unpack_model_archive(
            registration.archive, max_bytes=s.max_archive_bytes, max_entries=s.max_archive_entries
        )
    model, created = register_model(
        session=session,
        registry=ctx.models,
        max_urdf_bytes=s.max_urdf_bytes,
        registration=ModelRegistration(
            urdf=fields.urdf,
            files=files,
            base=fields.base,
            joint_names=fields.joint_names,
            group=fields.group,
            srdf=fields.srdf,
            joint_values=fields.joint_values,
            name=fields.name,
            acceleration_limits=fields.acceleration_limits,
            jerk_limits=fields.jerk_limits,
            end_effector_link=fields.end_effector_link,
        ),
    )
    if not created:
        response.status_code = 200
    return RobotModelOut(
        model_id=model.model_id,
        name=model.name,
        joint_names=list(model.joint_names),
        base=model.base.value,
        state_names=list(model.state_names),
        created=created,
        **_semantics(model, ctx.validators.geometry),
    )


@router.get(
    "",
    response_model=RobotModelPage,
    summary="List registered robot models",
    description="Registered models, oldest first, a page at a time (`limit`, `offset`).",
    responses=errors(
        {
            422: (
                "A page larger than max_page_size",
                "query.limit: 5000 is above max_page_size=1000",
            ),
        }
    ),
)
def list_models_route(session: SessionDep, page: PageDep) -> RobotModelPage:
    """Registered models, oldest first."""
    rows, total = list_models(session=session, limit=page.limit, offset=page.offset)
    items = [
        RobotModelSummary(
            model_id=row.id,
            name=row.name,
            base=row.base,
            joint_names=row.joint_names,
            state_names=state_names(row.base, row.joint_names),
            created_at=row.created_at,
        )
        for row in rows
    ]
    return RobotModelPage(items=items, total=total, limit=page.limit, offset=page.offset)


def _finite_or_none(values: Any) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


@router.get(
    "/{model_id}",
    response_model=RobotModelDetail,
    summary="A robot model: joints, links, limits and files",
    description="The model's planning joints and state order, link names, planning limits per "
    "state value (null = unbounded), velocity limits and stored mesh files.",
    responses=errors({404: ("Unknown model", "robot model '5158592d' not found")}),
)
def get_model_route(model_id: str, ctx: CtxDep, session: SessionDep) -> RobotModelDetail:
    """The model `model_id`."""
    # The model first: loading it reads the URDF, which get_model_row leaves unloaded.
    model = get_model(session=session, registry=ctx.models, model_id=model_id)
    row = get_model_row(session=session, model_id=model_id)
    files = list_model_files(session=session, model_id=model_id)
    limits = kinematic_limits(model, ctx.settings)
    return RobotModelDetail(
        model_id=row.id,
        name=row.name,
        base=model.base.value,
        joint_names=list(model.joint_names),
        state_names=list(model.state_names),
        created_at=row.created_at,
        link_names=list(model.link_names),
        lower=_finite_or_none(model.lower),
        upper=_finite_or_none(model.upper),
        velocity_limits=[float(v) for v in model.velocity_limits],
        acceleration_limits=limits.acceleration.tolist(),
        jerk_limits=limits.jerk.tolist(),
        end_effector_link=model.link_names[end_effector_link(model)],
        files=[ModelFileOut(path=f.path, sha256=f.sha256, size=f.size) for f in files],
        **_semantics(model, ctx.validators.geometry),
    )


def _semantics(model: RobotModel, geometry: GeometryCache) -> dict[str, Any]:
    """The skipped self-collision pairs, held joints and named states of a model's answer."""
    skipped = geometry.robot(model).skipped_link_pairs()
    return {
        "skipped_pairs": [SkippedPairOut(links=(a, b), reason=why) for a, b, why in skipped],
        "held_joints": dict(model.held_values),
        "named_states": {name: list(values) for name, values in model.named_states.items()},
        "warnings": list(model.warnings),
    }
