"""The dashboard's 3D view in headless Chromium (WebGL on SwiftShader), over the real service.

For the reference robot (primitives, a planar base, in the restroom) and for the
`example-robot-data` Panda (meshes, with its SRDF): a trajectory stored in a scene, and a plan
event whose cached candidate an obstacle placed in its way made the service reject. The view of
each trajectory must draw the robot (robot-coloured pixels where it stands) and change when
scrubbed; the view of each event must open at the failure with the link and the obstacle in
the highlight colour; the browser must log no error. Screenshots go to `artifacts/` (the
restroom rejection is also the README's `docs/images/view3d.png`, written there when
TRAJCACHE_README_SCREENSHOT=1).

Needs Debian's chromium (`/usr/bin/chromium`): skipped without it, failed when
TRAJCACHE_REQUIRE_SERVICES=1.
"""

from __future__ import annotations

import base64
import io
import os
import shutil
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from tests.dashboard.test_dashboard import ARTIFACTS, CHROMIUM, WAIT_MS, _require_browser, _service
from tests.waiting import wait_until
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import Shape, ShapeKind
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.path_quality import end_effector_link
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.geometry.scene.scene import Scene, SceneObject, make_scene
from trajcache.geometry.validation.validator import TrajectoryValidator, ValidationStatus
from trajcache.reference.cleaning import cleaning_run
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import reference_urdf

pytestmark = pytest.mark.slow

README_IMAGE = Path(__file__).resolve().parents[2] / "docs" / "images" / "view3d.png"
# WebGL in headless Chromium without a GPU: ANGLE on SwiftShader, the software renderer.
GL_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
PANDA_READY = [0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398]
OBSTACLE = 0.09  # m, the side of the box put in a stored path's way


@dataclass
class Staged:
    """What one robot's part of the service holds: a trajectory and a rejecting plan event."""

    name: str
    trajectory_id: int
    event_id: int
    link: str  # the link and the object the event's rejection names
    other: str
    candidate: int  # the trajectory the event rejected


def _rgb(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)


def _robot_pixels(image: np.ndarray) -> np.ndarray:
    """Where the robot's orange is (lit or shaded): red well above blue, green between."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (r > 110) & (r - b > 70) & (g > 0.3 * r) & (g < 0.85 * r)


def _highlight_pixels(image: np.ndarray) -> np.ndarray:
    """The unlit magenta of the link and the object at fault."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (r > 220) & (b > 220) & (g < 60)


def _obstacle_in_the_way(model: RobotModel, scene: Scene, path: np.ndarray) -> Scene | None:
    """`scene` with a box at the end effector halfway along `path`, if that blocks the path
    and leaves its start and goal clear; None otherwise."""
    middle = (path[0] + path[-1]) / 2.0
    tip = link_transforms(model, middle)[0][end_effector_link(model)]
    pose = np.eye(4)
    pose[:3, 3] = tip[:3, 3]
    box = SceneObject("cart", Shape(ShapeKind.BOX, (OBSTACLE,) * 3), pose)
    blocked = make_scene([*scene.objects, box], scene.env)
    validator = TrajectoryValidator(model, blocked)
    ends_clear = not any(validator.checker.state_contacts(s) for s in (path[0], path[-1]))
    collides = validator.validate(path).status is ValidationStatus.COLLISION
    return blocked if ends_clear and collides else None


def _post(client: httpx.Client, path: str, **kwargs: Any) -> Any:
    reply = client.post(path, **kwargs)
    assert reply.status_code in (200, 201), reply.text
    return reply.json()


def _put(client: httpx.Client, path: str, body: Any) -> Any:
    reply = client.put(path, json=body)
    assert reply.status_code in (200, 201), reply.text
    return reply.json()


def _stage(
    client: httpx.Client, name: str, model_id: str, model: RobotModel,
    scene: Scene, shown: np.ndarray, blocked_path: np.ndarray,
) -> Staged:  # fmt: skip
    """Robot `name` in `scene`: `shown` stored there; `blocked_path` stored, then blocked by an
    obstacle and asked for (no planning): its plan event rejects it."""
    robot = f"{name}-1"
    _put(client, f"/v1/robots/{robot}", {"model_id": model_id})
    version = _put(client, f"/v1/robots/{robot}/scene", scene_to_payload(scene))
    stored = {"model_id": model_id, "scene_hash": version["hash"], "source": "sim"}
    trajectory = _post(client, "/v1/trajectories", json={**stored, "states": shown.tolist()})
    _post(client, "/v1/trajectories", json={**stored, "states": blocked_path.tolist()})
    blocked = _obstacle_in_the_way(model, scene, blocked_path)
    assert blocked is not None, f"no obstacle blocks the {name}'s path and spares its ends"
    _put(client, f"/v1/robots/{robot}/scene", scene_to_payload(blocked))
    body = {"start": blocked_path[0].tolist(), "goal": blocked_path[-1].tolist(),
            "options": {"fallback": False}}  # fmt: skip
    assert _post(client, f"/v1/robots/{robot}/plan", json=body)["status"] == "miss"
    found: list[Any] = []

    def recorded() -> bool:  # events are written just after the answer
        params = {"robot_id": robot, "status": "miss"}
        found[:] = client.get("/v1/plan-events", params=params).json()["items"]
        return bool(found)

    assert wait_until(recorded, timeout_s=30, interval_s=0.05), "the plan left no event"
    [event] = found
    [pair, *_] = event["rejections"][0]["pairs"]
    assert pair["other"] == "cart", pair
    candidate = event["rejections"][0]["trajectory_id"]
    return Staged(
        name, trajectory["trajectory_id"], event["event_id"], pair["link"], "cart", candidate
    )


def _reference(client: httpx.Client) -> Staged:
    """The reference robot in the restroom: a drive between stations, and an arm motion."""
    model_id = _post(client, "/v1/robot-models",
                     json={"urdf": reference_urdf(), "base": "planar"})["model_id"]  # fmt: skip
    model = load_robot_model(reference_urdf(), base="planar")
    run = cleaning_run(11)
    drive = next(c for c in run.calls if c.base_moves)
    scene = run.scene_for(drive)
    arm_moves = [c for c in run.calls if not c.base_moves and run.scene_for(c) is scene]
    for call in sorted(arm_moves, key=lambda c: -float(np.abs(c.goal - c.start).max())):
        path = np.stack([call.start, call.goal])
        if _obstacle_in_the_way(model, scene, path) is not None:
            shown = np.stack([drive.start, drive.goal])
            return _stage(client, "cleaner", model_id, model, scene, shown, path)
    raise AssertionError("no arm motion of the run can be blocked cleanly")


def _panda(client: httpx.Client) -> Staged:
    """The Panda, meshes and SRDF as shipped, over a table: two sweeps of its first joint."""
    panda = ROBOTS["panda"]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for path, data in panda.files().items():
            archive.writestr(path, data)
    body = {"urdf": panda.urdf, "srdf": panda.srdf, "group": "arm",
            "archive_base64": base64.b64encode(buffer.getvalue()).decode()}  # fmt: skip
    model_id = _post(client, "/v1/robot-models", json=body)["model_id"]
    model = load_robot_model(panda.urdf, files=panda.files(), srdf=panda.srdf, group="arm")
    table = np.eye(4)
    table[:3, 3] = [0.55, 0.0, -0.2]
    scene = make_scene([SceneObject("table", Shape(ShapeKind.BOX, (0.6, 1.2, 0.05)), table)], {})
    ready = np.array(PANDA_READY)
    sweep = ready + np.array([[-1.2, 0, 0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0, 0, 0]])
    shown = ready + np.array([[0.9, 0.5, 0, 0.6, 0, 0, 0], [-0.9, -0.2, 0, -0.3, 0, 0, 0]])
    return _stage(client, "panda", model_id, model, scene, shown, sweep)


@pytest.fixture(scope="module")
def staged(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, list[Staged]]]:
    """The service on loopback with both robots' trajectories and rejecting plan events."""
    _require_browser()
    with _service(tmp_path_factory.mktemp("view3d")) as (base, _env):
        with httpx.Client(base_url=base, timeout=120) as client:
            robots = [_reference(client), _panda(client)]
        yield base, robots


@pytest.fixture
def gl_page() -> Iterator[tuple[Any, list[str]]]:
    """A Chromium page with WebGL, and the errors it logs (console errors, uncaught ones)."""
    sync_api = _require_browser()
    errors: list[str] = []
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=GL_ARGS
        )
        try:
            tab = browser.new_page(viewport={"width": 1400, "height": 1000})
            tab.on(
                "console",
                lambda m: errors.append(f"{m.type}: {m.text}") if m.type == "error" else None,
            )
            tab.on("pageerror", lambda exc: errors.append(f"uncaught: {exc}"))
            yield tab, errors
        finally:
            browser.close()


def _open(tab: Any, base: str, show: str) -> None:
    """Open the dashboard and show `show` ("trajectory:ID" or "event:ID") in the 3D view."""
    tab.goto(f"{base}/dashboard/")
    tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
    tab.eval_on_selector("#view3d", f"v => {{ v.dataset.show = '{show}'; }}")
    tab.wait_for_function(
        f"document.getElementById('view3d').dataset.loaded === '{show}'"
        " && document.getElementById('view3d').dataset.state === 'ready'",
        timeout=WAIT_MS,
    )
    tab.locator("#view3d").scroll_into_view_if_needed()


def _canvas(tab: Any, name: str) -> np.ndarray:
    ARTIFACTS.mkdir(exist_ok=True)
    png = tab.locator("#view3d-canvas canvas").screenshot(path=str(ARTIFACTS / name))
    return _rgb(png)


def _scrub(tab: Any, frame: int) -> None:
    tab.eval_on_selector(
        "#view3d-scrub",
        f"s => {{ s.value = '{frame}'; s.dispatchEvent(new Event('input')); }}",
    )
    tab.wait_for_function(f"document.getElementById('view3d').dataset.frame === '{frame}'")


@pytest.mark.parametrize("robot", [0, 1], ids=["reference", "panda"])
def test_a_stored_trajectory_is_drawn_and_scrubbed(
    gl_page: tuple[Any, list[str]], staged: tuple[str, list[Staged]], robot: int
) -> None:
    tab, errors = gl_page
    base, robots = staged
    shown = robots[robot]
    _open(tab, base, f"trajectory:{shown.trajectory_id}")
    view = tab.locator("#view3d")
    frames = int(view.get_attribute("data-frames") or 0)
    assert frames > 10 and view.get_attribute("data-highlighted") == ""
    assert f"scene v1 of {shown.name}-1" in tab.inner_text("#view3d-title")  # stored there
    first = _canvas(tab, f"view3d-{shown.name}-start.png")
    x0, y0, x1, y1 = (int(v) for v in (view.get_attribute("data-robot-box") or "").split(","))
    assert x1 - x0 > 20 and y1 - y0 > 20, (x0, y0, x1, y1)
    standing = _robot_pixels(first[y0:y1, x0:x1]).sum()
    assert standing > 0.04 * (x1 - x0) * (y1 - y0), standing  # the robot is drawn where it is
    assert _robot_pixels(first).sum() - standing < standing  # ...and mostly nowhere else
    _scrub(tab, frames - 1)
    last = _canvas(tab, f"view3d-{shown.name}-end.png")
    changed = np.abs(last - first).sum(axis=2) > 40
    assert changed.mean() > 0.005, changed.mean()  # scrubbing moved the robot
    assert _robot_pixels(last).sum() > 0
    tab.focus("#view3d-canvas")
    tab.keyboard.press("Home")  # keys: Home, End, arrows step, space plays
    tab.wait_for_function("document.getElementById('view3d').dataset.frame === '0'")
    tab.keyboard.press("ArrowRight")
    tab.wait_for_function("document.getElementById('view3d').dataset.frame === '1'")
    tab.click("#view3d-play")  # plays on from there, to the end
    tab.wait_for_function(
        f"document.getElementById('view3d').dataset.frame === '{frames - 1}'", timeout=WAIT_MS
    )
    assert tab.inner_text("#view3d-play") == "Play"  # stopped at the end
    assert not errors, errors


@pytest.mark.parametrize("robot", [0, 1], ids=["reference", "panda"])
def test_a_rejected_candidate_opens_at_its_failure_with_link_and_object_highlighted(
    gl_page: tuple[Any, list[str]], staged: tuple[str, list[Staged]], robot: int
) -> None:
    tab, errors = gl_page
    base, robots = staged
    shown = robots[robot]
    _open(tab, base, f"event:{shown.event_id}")
    view = tab.locator("#view3d")
    assert view.get_attribute("data-failure") == "shown"
    assert set((view.get_attribute("data-highlighted") or "").split(",")) == {
        shown.link,
        shown.other,
    }
    info = tab.inner_text("#view3d-info")
    assert f"link '{shown.link}' hits object 'cart'" in info and "at sample" in info
    assert f"scene v2 of {shown.name}-1" in tab.inner_text("#view3d-title")  # validated there
    name = f"view3d-{shown.name}-rejected.png"
    image = _canvas(tab, name)
    magenta = _highlight_pixels(image).sum()
    assert magenta > 150, magenta  # the link and the object at fault, in the highlight colour
    assert _robot_pixels(image).sum() > 150  # the rest of the robot as usual
    frame = int(view.get_attribute("data-frame") or 0)
    _scrub(tab, 0)  # away from the failure: the path's first frame
    assert int(view.get_attribute("data-frame") or 0) != frame or frame == 0
    assert view.get_attribute("data-failure") == ""
    tab.click("#view3d-failure")
    tab.wait_for_function("document.getElementById('view3d').dataset.failure === 'shown'")
    section = ARTIFACTS / f"view3d-{shown.name}-rejected-section.png"
    tab.locator("#view3d").screenshot(path=str(section))  # controls, the view, what failed
    if robot == 0 and os.environ.get("TRAJCACHE_README_SCREENSHOT") == "1":
        README_IMAGE.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(section, README_IMAGE)
    assert not errors, errors


def test_the_events_table_opens_an_event_in_the_3d_view(
    gl_page: tuple[Any, list[str]], staged: tuple[str, list[Staged]]
) -> None:
    tab, errors = gl_page
    base, robots = staged
    tab.goto(f"{base}/dashboard/")
    tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
    link = tab.locator(f"#events-table a.view3d-link[data-event='{robots[1].event_id}']")
    assert link.inner_text() == "why (1)"
    link.click()
    tab.wait_for_function(
        f"document.getElementById('view3d').dataset.loaded === 'event:{robots[1].event_id}'",
        timeout=WAIT_MS,
    )
    assert tab.get_attribute("#view3d", "data-failure") == "shown"
    assert not errors, errors


def _names_everywhere(tab: Any, base: str, event_id: int, trajectory_id: int) -> None:
    """Open `#event=<event_id>`: the 3D view, the inspector and the usage history must all name
    trajectory `trajectory_id`."""
    tab.goto(f"{base}/dashboard/#event={event_id}")
    tab.wait_for_function("document.body.dataset.state === 'ready'", timeout=WAIT_MS)
    tab.wait_for_function(
        f"document.getElementById('view3d').dataset.loaded === 'event:{event_id}'"
        f" && document.getElementById('inspect-meta').textContent.startsWith('#{trajectory_id} ')",
        timeout=WAIT_MS,
    )
    assert tab.get_attribute("#view3d", "data-trajectory") == str(trajectory_id)
    assert f"plan event #{event_id} " in tab.inner_text("#view3d-title")
    assert f"#{trajectory_id} " in tab.inner_text("#view3d-title") + " "
    assert tab.input_value("#inspect-id") == str(trajectory_id)
    assert tab.inner_text("#usage-title") == f"Usage history of trajectory #{trajectory_id}"


def test_a_deep_link_to_an_event_shows_its_trajectory_in_view_inspector_and_history(
    gl_page: tuple[Any, list[str]], staged: tuple[str, list[Staged]]
) -> None:
    """Runs last: it adds a robot and a hit to the staged service."""
    tab, errors = gl_page
    base, robots = staged
    panda = robots[1]
    with httpx.Client(base_url=base, timeout=120) as client:
        [top] = client.get("/v1/stats/top-trajectories", params={"limit": 1}).json()
        # what the page shows unasked: another robot's trajectory, not the event's
        assert top["trajectory_id"] != panda.candidate
        _names_everywhere(tab, base, panda.event_id, panda.candidate)
        assert "rejected candidate" in tab.inner_text("#view3d-title")
        model = tab.locator("#inspect-meta span.model")
        model_id = client.get(f"/v1/trajectories/{panda.candidate}").json()["model_id"]
        assert model.get_attribute("title") == model_id  # the hash on hover, the name shown
        assert model.inner_text() == client.get(f"/v1/robot-models/{model_id}").json()["name"]
        before = int(tab.get_attribute("body", "data-refreshes") or 0)
        tab.click("#refresh")  # a refresh keeps the selection
        tab.wait_for_function(f"Number(document.body.dataset.refreshes) > {before}")
        assert tab.inner_text("#inspect-meta").startswith(f"#{panda.candidate} ")
        assert tab.get_attribute("#view3d", "data-loaded") == f"event:{panda.event_id}"

        # A second Panda in the first scene is served the stored path: an event with a hit.
        scene = client.get("/v1/robots/panda-1/scenes/1").json()
        _put(client, "/v1/robots/panda-2", {"model_id": model_id})
        first_scene = {"objects": scene["objects"], "env": scene["env"]}
        _put(client, "/v1/robots/panda-2/scene", first_scene)
        states = client.get(f"/v1/trajectories/{panda.candidate}").json()["states"]
        body = {"start": states[0], "goal": states[-1], "options": {"fallback": False}}
        answer = _post(client, "/v1/robots/panda-2/plan", json=body)
        assert answer["trajectory_id"] == panda.candidate, answer
        wait_until(
            lambda: client.get("/v1/plan-events", params={"robot_id": "panda-2"}).json()["items"],
            timeout_s=30,
        )
        [hit] = client.get("/v1/plan-events", params={"robot_id": "panda-2"}).json()["items"]
    _names_everywhere(tab, base, hit["event_id"], panda.candidate)  # the same page: a new hash
    usage = "#usage-table tbody tr"
    tab.wait_for_function(f"document.querySelectorAll('{usage}')[0].cells.length > 1")
    robots = tab.eval_on_selector_all(usage, "rows => rows.map(r => r.cells[1].textContent)")
    assert robots == ["panda-2"]  # the event itself, in the trajectory's history
    assert not errors, errors
