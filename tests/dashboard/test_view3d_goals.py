"""The 3D view's goal markers in headless Chromium, over the real service, on the
`example-robot-data` Panda: a plan event whose goal was the hand's pose shows a frame marker
there (its red x axis drawn), and a Cartesian path its straight line as a green polyline; the
browser logs no error. Needs Debian's chromium, as `test_view3d`."""

from __future__ import annotations

import base64
import io
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.dashboard.test_dashboard import _require_browser, _service
from tests.dashboard.test_view3d import PANDA_READY, _canvas, _open, gl_page  # noqa: F401
from tests.waiting import wait_until
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.example_robots import ROBOTS

pytestmark = pytest.mark.slow

HAND = "panda_hand"


@dataclass
class Goals:
    base: str
    event_id: int  # a hit for a pose goal
    goal: list[float]  # its position
    path_id: int  # a Cartesian path


def _ok(reply: httpx.Response) -> Any:
    assert reply.status_code in (200, 201), reply.text
    return reply.json()


def _hand(state: np.ndarray) -> np.ndarray:
    panda = ROBOTS["panda"]
    model = load_robot_model(panda.urdf, files=panda.files(), srdf=panda.srdf, group="arm")
    return link_transforms(model, state)[0, model.link_names.index(HAND)]


def _stage(client: httpx.Client) -> tuple[int, list[float], int]:
    """An empty-scene Panda: a pose goal answered from the cache, a 10 cm Cartesian approach."""
    panda = ROBOTS["panda"]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in panda.files().items():
            archive.writestr(name, data)
    body = {"urdf": panda.urdf, "srdf": panda.srdf, "group": "arm",
            "archive_base64": base64.b64encode(buffer.getvalue()).decode()}  # fmt: skip
    model_id = _ok(client.post("/v1/robot-models", json=body))["model_id"]
    _ok(client.put("/v1/robots/goals-1", json={"model_id": model_id}))
    _ok(client.put("/v1/robots/goals-1/scene", json={"objects": []}))
    ready = np.array(PANDA_READY)
    end = ready + np.array([0.4, 0.2, 0.0, 0.3, 0.0, 0.0, 0.0])
    _ok(client.post("/v1/trajectories", json={"model_id": model_id, "states": [ready.tolist(),
                                              end.tolist()]}))  # fmt: skip
    pose = _hand(end)
    goal = {"link": HAND, "position": pose[:3, 3].tolist(),
            "orientation": Rotation.from_matrix(pose[:3, :3]).as_quat().tolist()}  # fmt: skip
    body = {"start": PANDA_READY, "goal_pose": goal, "options": {"fallback": False}}
    assert _ok(client.post("/v1/robots/goals-1/plan", json=body))["source"] == "cache"
    events: list[Any] = []

    def recorded() -> bool:
        events[:] = _ok(client.get("/v1/plan-events", params={"robot_id": "goals-1"}))["items"]
        return bool(events)

    assert wait_until(recorded, timeout_s=30, interval_s=0.05), "the plan left no event"
    start = _hand(ready)
    waypoint = {"position": (start[:3, 3] + 0.1 * start[:3, 2]).tolist(),
                "orientation": Rotation.from_matrix(start[:3, :3]).as_quat().tolist()}  # fmt: skip
    body = {"start": PANDA_READY, "link": HAND, "waypoints": [waypoint]}
    path = _ok(client.post("/v1/robots/goals-1/cartesian-path", json=body))
    assert path["fraction"] == 1.0
    return events[0]["event_id"], goal["position"], path["path_id"]


@pytest.fixture(scope="module")
def goals(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Goals]:
    _require_browser()
    with (
        _service(tmp_path_factory.mktemp("goals")) as (base, _env),
        httpx.Client(base_url=base, timeout=120) as client,
    ):
        yield Goals(base, *_stage(client))


def _coloured(image: np.ndarray, rgb: tuple[int, int, int]) -> int:
    """Pixels within 40 of `rgb` in every channel."""
    return int((np.abs(image.astype(int) - np.array(rgb)).max(axis=2) < 40).sum())


def test_a_pose_goal_is_drawn_as_a_frame_marker(
    gl_page: tuple[Any, list[str]],  # noqa: F811
    goals: Goals,
) -> None:
    tab, errors = gl_page
    _open(tab, goals.base, f"event:{goals.event_id}")
    shown = tab.get_attribute("#view3d", "data-goal") or ""
    assert [float(v) for v in shown.split(",")] == pytest.approx(goals.goal, abs=1e-3)
    assert tab.get_attribute("#view3d", "data-waypoints") == ""
    assert _coloured(_canvas(tab, "view3d-goal-pose.png"), (255, 0, 0)) > 10  # the x axis
    assert not errors, errors


def test_a_cartesian_paths_lines_are_drawn(
    gl_page: tuple[Any, list[str]],  # noqa: F811
    goals: Goals,
) -> None:
    tab, errors = gl_page
    _open(tab, goals.base, f"cartesian:{goals.path_id}")
    assert tab.get_attribute("#view3d", "data-waypoints") == "1"
    assert tab.get_attribute("#view3d", "data-goal") == ""
    assert "Cartesian path" in tab.inner_text("#view3d-title")
    assert _coloured(_canvas(tab, "view3d-cartesian.png"), (0x1A, 0x7F, 0x37)) > 10
    assert not errors, errors
