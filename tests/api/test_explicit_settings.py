"""The quality of a stored trajectory follows the app's settings, not the process environment's:
through POST /v1/trajectories and through an import (computed in the background)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.api.conftest import ClientFactory, ctx_of, register
from tests.waiting import wait_until
from trajcache.core.config import Settings
from trajcache.services.catalog.models import get_model
from trajcache.services.catalog.trajectories import quality_columns

SLOW = {"worker_backend": "none", "timing_joint_acceleration": 0.25}  # the default is 5.0
POSTED = [[0.0, 0.0], [0.5, 0.4], [1.0, 0.2]]
IMPORTED = [[0.0, 0.1], [0.6, 0.5], [1.1, 0.3]]


def durations(client: object, model_id: str, states: list[list[float]]) -> tuple[float, float]:
    """The duration under the app's settings and under the environment's (defaults)."""
    ctx = ctx_of(client)  # type: ignore[arg-type]
    with ctx.sessions() as session:
        model = get_model(session=session, registry=ctx.models, model_id=model_id)
    array = np.asarray(states)
    app = quality_columns(model, array, ctx.settings, None)
    env = quality_columns(model, array, Settings(), None)
    assert app is not None and env is not None
    return float(app["duration_s"]), float(env["duration_s"])


def test_post_stores_quality_under_the_apps_settings(client_factory: ClientFactory) -> None:
    client = client_factory(**SLOW)
    model_id = register(client)["model_id"]
    posted = client.post(
        "/v1/trajectories", json={"model_id": model_id, "states": POSTED, "source": "sim"}
    )
    assert posted.status_code == 201, posted.text
    stored = client.get(f"/v1/trajectories/{posted.json()['trajectory_id']}").json()
    app, env = durations(client, model_id, POSTED)
    assert app > 1.5 * env  # the settings differ enough to tell apart
    assert stored["duration_s"] == pytest.approx(app)
    assert stored["quality_pending"] is False


def test_import_quality_is_pending_then_computed_under_the_apps_settings(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(**SLOW, quality_backfill_per_s=100)
    model_id = register(client)["model_id"]
    lines = [
        {"type": "header", "format": "trajcache-export", "version": 2, "filters": {}},
        {"type": "trajectory", "model_id": model_id, "states": IMPORTED, "source": "sim"},
        {"type": "end", "trajectories": 1},
    ]
    body = "\n".join(json.dumps(line) for line in lines).encode()
    report = client.post("/v1/admin/import", content=body)
    assert report.status_code == 200 and report.json()["inserted"] == 1, report.text
    (item,) = client.get("/v1/trajectories", params={"model_id": model_id}).json()["items"]

    def stored() -> dict[str, object]:
        body: dict[str, object] = client.get(f"/v1/trajectories/{item['trajectory_id']}").json()
        return body

    assert wait_until(lambda: stored()["quality_pending"] is False, timeout_s=60, interval_s=0.2)
    app, env = durations(client, model_id, IMPORTED)
    assert app > 1.5 * env
    assert stored()["duration_s"] == pytest.approx(app)
