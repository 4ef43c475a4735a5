"""The body of the liveness and readiness answers."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict

from trajcache.api.schemas.common import examples


class HealthOut(BaseModel):
    """Liveness or readiness."""

    model_config = ConfigDict(json_schema_extra=examples({"status": "ok"}, {"status": "ready"}))

    status: Literal["ok", "ready"]
