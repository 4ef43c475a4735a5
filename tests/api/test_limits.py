"""Input limits on every route: body size, scene objects (seed jobs too), page sizes, option
bounds and malformed bodies, each a 413 or 422 whose detail names the limit."""

from __future__ import annotations

import io
import json
from collections.abc import Iterable, Iterator
from typing import Any

import pytest
from fastapi.routing import APIRoute
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, register
from tests.robots import OPAQUE_URDF
from trajcache.api.bounded import BoundedBodyRoute

BODY_LIMIT = 4000
FAST = {"worker_backend": "none", "auth_mode": "off"}
BOX = {"id": "b", "type": "box", "size": [0.1, 0.1, 0.1], "pose": {"position": [1, 1, 1]}}
PADDING = "x" * (BODY_LIMIT + 10)

# Every route that takes a body, with a body past BODY_LIMIT.
BODY_ROUTES = [
    ("POST", "/v1/robots/r/plan", {"start": [0, 0], "goal": [0, 0], "pad": PADDING}),
    ("PUT", "/v1/robots/r", {"model_id": PADDING}),
    ("PUT", "/v1/robots/r/scene", {"objects": [], "env": {PADDING: 1.0}}),
    ("PATCH", "/v1/robots/r/scene", {"remove": [PADDING]}),
    ("POST", "/v1/trajectories", {"model_id": "m", "states": [[0.0, 0.0]] * 500}),
    ("POST", "/v1/seed-jobs", {"model_id": "m", "name": PADDING}),
    ("POST", "/v1/admin/prune", {"model_id": PADDING}),
    ("POST", "/v1/admin/import", PADDING),
]


@pytest.fixture
def client(client_factory: ClientFactory) -> TestClient:
    """Checks off, no planner, small body and page limits, a robot `r` of the 2-joint model."""
    client = client_factory(**FAST, max_body_bytes=BODY_LIMIT, max_page_size=20)
    model_id = register(client)["model_id"]
    assert client.put("/v1/robots/r", json={"model_id": model_id}).status_code == 201
    return client


def _send(client: TestClient, method: str, url: str, body: Any, **kwargs: Any) -> Any:
    if isinstance(body, str):
        return client.request(method, url, content=body.encode(), **kwargs)
    return client.request(method, url, json=body, **kwargs)


def _api_routes(routes: Iterable[Any]) -> Iterator[APIRoute]:
    for route in routes:
        if isinstance(route, APIRoute):
            yield route
        nested = getattr(route, "original_router", route)  # an included router
        yield from _api_routes(getattr(nested, "routes", []))


def test_every_route_with_a_body_reads_it_bounded(app_client: TestClient) -> None:
    methods = {"POST", "PUT", "PATCH"}
    routes = [r for r in _api_routes(app_client.app.routes) if r.methods & methods]
    assert len(routes) >= 9
    unbounded = [r.path for r in routes if not isinstance(r, BoundedBodyRoute)]
    assert not unbounded, f"routes reading their body without a limit: {unbounded}"


@pytest.mark.parametrize(("method", "url", "body"), BODY_ROUTES, ids=lambda v: str(v)[:30])
def test_a_body_past_max_body_bytes_is_413(
    client: TestClient, method: str, url: str, body: Any
) -> None:
    assert_detail(_send(client, method, url, body), 413, f"max_body_bytes={BODY_LIMIT}")


@pytest.mark.parametrize(("method", "url", "body"), BODY_ROUTES, ids=lambda v: str(v)[:30])
def test_a_streamed_body_is_refused_once_it_passes_the_limit(
    client: TestClient, method: str, url: str, body: Any
) -> None:
    data = body.encode() if isinstance(body, str) else json.dumps(body).encode()

    def chunks() -> Iterator[bytes]:  # no content-length: the size is only known while read
        for start in range(0, len(data), 256):
            yield data[start : start + 256]

    response = client.request(
        method, url, content=chunks(), headers={"content-type": "application/json"}
    )
    assert_detail(response, 413, f"more than {BODY_LIMIT} bytes", "max_body_bytes")


def test_a_registration_is_bounded_by_the_urdf_and_archive_limits(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(**FAST, max_urdf_bytes=1000, max_archive_bytes=1000)
    archive = io.BytesIO(b"\0" * 200_000)  # far past what the two limits allow together
    response = client.post(
        "/v1/robot-models",
        data={"urdf": OPAQUE_URDF},
        files={"archive": ("a.zip", archive, "application/zip")},
    )
    assert_detail(response, 413, "request body has", "max_urdf_bytes=1000", "max_archive_bytes")


@pytest.mark.parametrize(
    ("method", "url"),
    [("POST", "/v1/robots/r/plan"), ("PATCH", "/v1/robots/r/scene"), ("POST", "/v1/seed-jobs")],
)
def test_json_that_is_not_utf8_or_nests_too_deeply_is_422(
    client: TestClient, method: str, url: str
) -> None:
    headers = {"content-type": "application/json"}
    latin1 = client.request(method, url, content='["tür"]'.encode("latin-1"), headers=headers)
    assert_detail(latin1, 422, "UTF-8")
    deep = client.request(method, url, content=b"[" * 1500 + b"]" * 1500, headers=headers)
    assert_detail(deep, 422, "nests too deeply")


def test_deeply_nested_scenes_and_import_lines_are_refused(client: TestClient) -> None:
    deep = "[" * 1000 + "]" * 1000
    for media in ("application/json", "application/yaml"):
        response = client.put(
            "/v1/robots/r/scene", content=deep.encode(), headers={"content-type": media}
        )
        assert_detail(response, 422, "nests too deeply")
    imported = client.post("/v1/admin/import", content=deep.encode())
    assert imported.status_code == 200, imported.text
    assert "nests too deeply" in imported.json()["rejected"][0]["reason"]


def test_scene_object_limit_applies_to_seed_job_scenes(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST, max_scene_objects=2)
    model_id = register(client)["model_id"]
    objects = [{**BOX, "id": f"b{i}"} for i in range(3)]
    query = {"start": [0, 0], "goal": [0.3, 0.3]}
    job = {"model_id": model_id, "queries": [query]}
    explicit = client.post("/v1/seed-jobs", json={**job, "scenes": [{"objects": objects}]})
    assert_detail(explicit, 413, "scenes[0]", "max_scene_objects=2")
    base = client.post("/v1/seed-jobs", json={**job, "base_scene": {"objects": objects}})
    assert_detail(base, 413, "base_scene", "max_scene_objects=2")
    grown = client.post(
        "/v1/seed-jobs",
        json={**job, "base_scene": {"objects": objects[:2]}, "variants": [{"upsert": objects}]},
    )
    assert_detail(grown, 413, "variants[0]", "max_scene_objects=2")
    assert client.get("/v1/seed-jobs").json()["total"] == 0


def test_scene_extent_applies_to_seed_job_scenes(client_factory: ClientFactory) -> None:
    client = client_factory(**FAST, max_scene_extent_m=20.0)
    model_id = register(client)["model_id"]
    far = {**BOX, "id": "far", "pose": {"position": [30.0, 0.0, 0.0]}}
    job = {"model_id": model_id, "queries": [{"start": [0, 0], "goal": [0.3, 0.3]}]}
    explicit = client.post("/v1/seed-jobs", json={**job, "scenes": [{"objects": [far]}]})
    assert_detail(explicit, 422, "scenes[0]", "'far'", "max_scene_extent_m=20")
    base = client.post("/v1/seed-jobs", json={**job, "base_scene": {"objects": [far]}})
    assert_detail(base, 422, "base_scene", "'far'")
    grown = client.post(
        "/v1/seed-jobs",
        json={**job, "base_scene": {"objects": []}, "variants": [{"upsert": [far]}]},
    )
    assert_detail(grown, 422, "variants[0]", "'far'")
    assert client.get("/v1/seed-jobs").json()["total"] == 0


LISTS = ["/v1/robot-models", "/v1/trajectories", "/v1/seed-jobs", "/v1/plan-events"]


@pytest.mark.parametrize("url", [*LISTS, "/v1/stats/top-trajectories"])
def test_every_list_caps_its_page_size(client: TestClient, url: str) -> None:
    assert_detail(client.get(url, params={"limit": 21}), 422, "max_page_size=20")
    assert client.get(url, params={"limit": 20}).status_code == 200


@pytest.mark.parametrize("url", LISTS)
def test_the_default_page_fits_a_small_max_page_size(client: TestClient, url: str) -> None:
    response = client.get(url)  # the default page size (100) is cut to max_page_size
    assert response.status_code == 200, response.text
    assert response.json()["limit"] == 20


@pytest.mark.parametrize("url", ["/v1/robot-models", "/v1/trajectories", "/v1/seed-jobs"])
def test_an_offset_past_64_bits_is_422(client: TestClient, url: str) -> None:
    assert_detail(client.get(url, params={"offset": 2**63}), 422, "query.offset")
    assert client.get(url, params={"offset": 2**63 - 1}).json()["items"] == []


@pytest.mark.parametrize(
    ("option", "value", "setting"),
    [
        ("budget_s", 31.0, "plan_budget_max_s=30.0"),
        ("threshold", 0.6, "lookup_threshold_max=0.5"),
        ("max_candidates", 11, "max_candidates_limit=10"),
    ],
)
def test_plan_options_past_their_limits_are_422_naming_the_setting(
    client: TestClient, option: str, value: float, setting: str
) -> None:
    body = {"start": [0, 0], "goal": [0.3, 0.3], "options": {option: value}}
    assert_detail(client.post("/v1/robots/r/plan", json=body), 422, f"options.{option}", setting)
    model_id = client.get("/v1/robots/r").json()["model_id"]
    job = {
        "model_id": model_id,
        "scenes": [{"objects": []}],
        "queries": [{"start": [0, 0], "goal": [0.3, 0.3]}],
        "options": {option: value},
    }
    assert_detail(client.post("/v1/seed-jobs", json=job), 422, f"options.{option}", setting)


def test_huge_counts_and_ages_are_422_not_server_errors(client: TestClient) -> None:
    assert_detail(client.post("/v1/admin/prune", json={"cap": 2**70}), 422, "body.cap")
    for name in ("newer_than_s", "older_than_s"):
        assert_detail(client.get("/v1/admin/export", params={name: 1e300}), 422, name)
