"""The scenes of a seed job: explicit ones, the restroom generator, variants and sweeps.

The formats are described in `trajcache.services.seeding.spec`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

from pydantic import Field, ValidationError

from trajcache.core.config import Settings
from trajcache.core.field_errors import readable_errors, validation_message
from trajcache.core.request_model import RequestModel
from trajcache.core.suggest import unknown_message
from trajcache.geometry.errors import GeometryError
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.scene.payload import apply_patch
from trajcache.geometry.scene.scene import Scene
from trajcache.reference.restroom import STALL_COUNT, restroom_scene
from trajcache.services.catalog.scene_limits import SceneLimits, check_scene
from trajcache.services.errors import InvalidInputError, PayloadTooLargeError
from trajcache.services.seeding.spec import FiniteFloat, Sweep

GENERATOR_PARAMS = ("doors_deg", "seats_deg")


class _Restroom(RequestModel):
    """Parameters of the restroom generator."""

    generator: Literal["restroom"] = "restroom"
    doors_deg: FiniteFloat | list[FiniteFloat] = 0.0
    seats_deg: FiniteFloat | list[FiniteFloat] = 0.0
    env: dict[str, FiniteFloat] = Field(default_factory=dict)
    jitter_m: FiniteFloat = Field(default=0.0, ge=0, le=0.2)
    jitter_seed: int | None = None


def _restroom_env_keys() -> list[str]:
    return [f"stall_{i}_{part}" for part in ("door", "seat") for i in range(1, STALL_COUNT + 1)]


def _per_stall(value: float | list[float], where: str) -> list[float]:
    values = [float(value)] * STALL_COUNT if isinstance(value, int | float) else list(value)
    if len(values) != STALL_COUNT:
        raise InvalidInputError(f"{where}: give one angle or {STALL_COUNT}, got {len(values)}")
    return values


def _build_restroom(params: Mapping[str, Any], where: str) -> Scene:
    try:
        spec = _Restroom.model_validate(params)
    except ValidationError as exc:
        raise InvalidInputError(f"{where}: {_pydantic_message(exc)}") from None
    doors = _per_stall(spec.doors_deg, f"{where}.doors_deg")
    seats = _per_stall(spec.seats_deg, f"{where}.seats_deg")
    for key, value in spec.env.items():
        parts = key.split("_")
        if key not in _restroom_env_keys():
            unknown = unknown_message("value", [key], _restroom_env_keys())
            raise InvalidInputError(f"{where}.env: {unknown} (the restroom's)")
        target = doors if parts[2] == "door" else seats
        target[int(parts[1]) - 1] = math.degrees(value)
    try:
        return restroom_scene(
            doors=doors, seats=seats, jitter_m=spec.jitter_m, seed=spec.jitter_seed
        )
    except GeometryError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None


def _pydantic_message(exc: ValidationError) -> str:
    return validation_message(readable_errors(exc.errors()))


def _explicit_scene(payload: Mapping[str, Any], where: str, limits: SceneLimits) -> Scene:
    try:
        scene = parse_scene(payload)
    except GeometryError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    check_scene(scene, limits, where)
    return scene


def _is_generator(payload: Mapping[str, Any]) -> bool:
    return "generator" in payload


def _check_generator(payload: Mapping[str, Any], where: str) -> None:
    if payload.get("generator") != "restroom":
        raise InvalidInputError(
            f"{where}.generator: unknown generator {payload.get('generator')!r}; use 'restroom'"
        )


def _merged(base: Mapping[str, Any], variant: Mapping[str, Any]) -> dict[str, Any]:
    out = {**base, **{k: v for k, v in variant.items() if k != "env"}}
    if "env" in variant:
        env = variant["env"]
        if not isinstance(env, Mapping):
            return {**out, "env": env}  # rejected with its location by the generator
        out["env"] = {**dict(base.get("env") or {}), **env}
    return out


def _sweep_variants(sweep: Sweep) -> list[dict[str, Any]]:
    if sweep.param in GENERATOR_PARAMS:
        return [{sweep.param: value} for value in sweep.values()]
    if sweep.param.startswith("env.") and len(sweep.param) > 4:
        key = sweep.param[4:]
        return [{"env": {key: value}} for value in sweep.values()]
    raise InvalidInputError(
        f"sweep.param: {sweep.param!r} is not one of {', '.join(GENERATOR_PARAMS)} or env.<name>"
    )


def build_scenes(
    *,
    scenes: Sequence[Mapping[str, Any]] | None,
    base_scene: Mapping[str, Any] | None,
    variants: Sequence[Mapping[str, Any]] | None,
    sweep: Sweep | None,
    settings: Settings,
) -> list[Scene]:
    """A job's scenes (explicit, generated, or variants of a base), validated."""
    limits = SceneLimits.of(settings)
    if scenes is not None:
        _check_count(len(scenes), settings)
        out = []
        for i, payload in enumerate(scenes):
            where = f"scenes[{i}]"
            if _is_generator(payload):
                _check_generator(payload, where)
                out.append(_build_restroom(payload, where))
            else:
                out.append(_explicit_scene(payload, where, limits))
        return out
    base = base_scene
    assert base is not None
    if sweep is not None:
        if not _is_generator(base):
            raise InvalidInputError(
                "sweep needs a generator base_scene; vary an explicit scene with variants "
                "(scene patches)"
            )
        variants = _sweep_variants(sweep)
        where_fmt = "sweep value {} (" + sweep.param + ")"
    else:
        variants = variants or [{}]
        where_fmt = "variants[{}]"
    _check_count(len(variants), settings)
    if _is_generator(base):
        _check_generator(base, "base_scene")
        _build_restroom(base, "base_scene")
        return [
            _build_restroom(_merged(base, v), where_fmt.format(i)) for i, v in enumerate(variants)
        ]
    parsed_base = _explicit_scene(base, "base_scene", limits)
    out = []
    for i, patch in enumerate(variants):
        where = where_fmt.format(i)
        try:
            scene = apply_patch(parsed_base, patch)
        except GeometryError as exc:
            raise InvalidInputError(f"{where}: {exc}") from None
        check_scene(scene, limits, where)
        out.append(scene)
    return out


def _check_count(scenes: int, settings: Settings) -> None:
    if scenes > settings.seed_max_scenes:
        raise PayloadTooLargeError(
            f"the job has {scenes} scenes, more than seed_max_scenes={settings.seed_max_scenes}"
        )
