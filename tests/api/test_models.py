"""POST/GET /v1/robot-models: JSON and multipart registration, idempotence, limits, safety."""

from __future__ import annotations

import base64
import hashlib
import io
import zipfile

import trimesh
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from tests.robots import (
    MESH_URDF,
    ONE_LINK_URDF,
    TWO_JOINT_URDF,
    box,
    collision,
    joint,
    link,
    robot,
)
from trajcache.services.catalog.models import get_model


def _stl() -> bytes:
    return bytes(trimesh.creation.box(extents=(0.1, 0.1, 0.2)).export(file_type="stl"))


def _zip(entries: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)
    return buffer.getvalue()


def test_register_json_is_idempotent(app_client: TestClient) -> None:
    first = app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "name": "arm"})
    assert first.status_code == 201, first.text
    body = first.json()
    assert body["created"] is True
    assert body["base"] == "fixed"
    assert body["joint_names"] == ["shoulder", "elbow"]
    assert body["state_names"] == ["shoulder", "elbow"]
    assert body["name"] == "arm"
    assert len(body["model_id"]) == 64

    again = app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "name": "arm"})
    assert again.status_code == 200
    assert again.json() == {**body, "created": False}

    listing = app_client.get("/v1/robot-models").json()
    assert listing["total"] == 1
    assert [m["model_id"] for m in listing["items"]] == [body["model_id"]]


def test_planar_base_and_joint_subset(app_client: TestClient) -> None:
    body = register(app_client, base="planar", joint_names=["elbow"])
    assert body["base"] == "planar"
    assert body["state_names"] == ["base_x", "base_y", "base_theta", "elbow"]
    other = register(app_client)
    assert other["model_id"] != body["model_id"]
    assert app_client.get("/v1/robot-models").json()["total"] == 2


def test_get_model_detail_and_unknown(app_client: TestClient) -> None:
    model_id = register(app_client)["model_id"]
    detail = app_client.get(f"/v1/robot-models/{model_id}").json()
    assert detail["link_names"] == ["base", "upper", "fore"]
    assert detail["lower"] == [-2.0, -1.5]
    assert detail["upper"] == [2.0, 1.5]
    assert detail["files"] == []
    assert_detail(app_client.get("/v1/robot-models/" + "0" * 64), 404, "not found")


def test_planar_limits_are_null_when_unbounded(app_client: TestClient) -> None:
    model_id = register(app_client, base="planar")["model_id"]
    detail = app_client.get(f"/v1/robot-models/{model_id}").json()
    assert detail["lower"][:2] == [None, None]
    assert detail["upper"][:2] == [None, None]


def test_multipart_with_archive_matches_json_base64(app_client: TestClient) -> None:
    stl = _stl()
    archive = _zip({"meshes/part.stl": stl, "meshes/unused.stl": stl + b"x"})
    response = app_client.post(
        "/v1/robot-models",
        data={"urdf": MESH_URDF, "base": "planar", "joint_names": " lift , ", "name": "m"},
        files={"archive": ("meshes.zip", archive, "application/zip")},
    )
    assert response.status_code == 201, response.text
    body = response.json()
    assert body["state_names"] == ["base_x", "base_y", "base_theta", "lift"]

    detail = app_client.get(f"/v1/robot-models/{body['model_id']}").json()
    assert detail["files"] == [
        {"path": "meshes/part.stl", "sha256": hashlib.sha256(stl).hexdigest(), "size": len(stl)}
    ]
    again = app_client.post(
        "/v1/robot-models",
        json={
            "urdf": MESH_URDF,
            "base": "planar",
            "joint_names": ["lift"],
            "archive_base64": base64.b64encode(archive).decode(),
        },
    )
    assert again.status_code == 200, again.text
    assert again.json()["model_id"] == body["model_id"]


def test_multipart_urdf_as_uploaded_file(app_client: TestClient) -> None:
    response = app_client.post(
        "/v1/robot-models",
        data={"base": "fixed"},
        files={"urdf": ("arm.urdf", TWO_JOINT_URDF.encode(), "application/xml")},
    )
    assert response.status_code == 201, response.text
    assert response.json()["joint_names"] == ["shoulder", "elbow"]


def test_model_loads_back_from_the_database(client_factory: ClientFactory) -> None:
    first = client_factory()
    archive = _zip({"meshes/part.stl": _stl()})
    body = register(
        first, MESH_URDF, archive_base64=base64.b64encode(archive).decode(), base="planar"
    )
    original = ctx_of(first).models.get(body["model_id"])
    assert original is not None

    second = client_factory()  # another replica: empty model cache
    ctx = ctx_of(second)
    assert body["model_id"] not in ctx.models

    with ctx.sessions() as session:
        loaded = get_model(session=session, registry=ctx.models, model_id=body["model_id"])
    assert loaded.model_id == body["model_id"]
    assert loaded.allowed_pairs == original.allowed_pairs
    assert loaded.state_names == original.state_names
    assert [e.shape.kind for e in loaded.elements] == [e.shape.kind for e in original.elements]


def test_entity_urdf_is_refused(app_client: TestClient) -> None:
    # A literal: the DOCTYPE with entities is what is tested.
    evil = (
        '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;">]>'
        '<robot name="&b;"><link name="l"/></robot>'
    )
    assert_detail(app_client.post("/v1/robot-models", json={"urdf": evil}), 422, "DOCTYPE")


def test_bad_urdf_and_fields_are_422(app_client: TestClient) -> None:
    truncated = "<robot"  # a literal: the malformation is what is tested
    assert_detail(
        app_client.post("/v1/robot-models", json={"urdf": truncated}), 422, "malformed URDF"
    )
    assert_detail(
        app_client.post(
            "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "joint_names": ["wrist"]}
        ),
        422,
        "wrist",
    )
    assert_detail(
        app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "base": "legs"}),
        422,
        "body.base",
    )
    assert_detail(
        app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "colour": "red"}),
        422,
        "body.colour",
    )
    assert_detail(app_client.post("/v1/robot-models", json={}), 422, "body.urdf")
    assert_detail(
        app_client.post(
            "/v1/robot-models",
            content=b'{"urdf": ',
            headers={"content-type": "application/json"},
        ),
        422,
        "invalid JSON",
    )
    assert_detail(
        app_client.post(
            "/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "archive_base64": "not base64!"}
        ),
        422,
        "archive_base64",
    )
    assert_detail(
        app_client.post("/v1/robot-models", content=b"urdf", headers={"content-type": "text/csv"}),
        415,
        "text/csv",
    )


def test_a_model_with_nothing_to_plan_is_422(app_client: TestClient) -> None:
    cart = robot(
        "cart",
        link("base", collision(box(0.5, 0.4, 0.3))),
        link("mast", collision(box(0.1, 0.1, 1.0))),
        joint("mast_mount", "fixed", "base", "mast", xyz=(0, 0, 0.6)),
    )
    for urdf in (cart, ONE_LINK_URDF):
        reply = app_client.post("/v1/robot-models", json={"urdf": urdf})
        assert_detail(reply, 422, "nothing to plan", "only fixed joints", "base 'planar'")
    held = app_client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF, "joint_names": []})
    assert_detail(held, 422, "nothing to plan", "every movable joint is held")
    mobile = register(app_client, urdf=cart, base="planar")  # the base is what moves
    assert mobile["state_names"] == ["base_x", "base_y", "base_theta"]
    assert app_client.get("/v1/robot-models").json()["total"] == 1


def test_missing_mesh_and_escaping_archive_are_422(app_client: TestClient) -> None:
    assert_detail(app_client.post("/v1/robot-models", json={"urdf": MESH_URDF}), 422, "part.stl")
    escaping = _zip({"../outside.stl": _stl()})
    response = app_client.post(
        "/v1/robot-models",
        data={"urdf": MESH_URDF},
        files={"archive": ("a.zip", escaping, "application/zip")},
    )
    assert_detail(response, 422, "escapes")


def test_size_limits(client_factory: ClientFactory) -> None:
    client = client_factory(max_urdf_bytes=len(TWO_JOINT_URDF) - 1, max_archive_bytes=4096)
    assert_detail(
        client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}), 413, "max_urdf_bytes"
    )
    assert_detail(
        client.post("/v1/robot-models", data={"urdf": TWO_JOINT_URDF}), 413, "max_urdf_bytes"
    )
    multipart_field = {"urdf": (None, TWO_JOINT_URDF.encode())}  # a field, not a file
    assert_detail(client.post("/v1/robot-models", files=multipart_field), 413, "max_urdf_bytes")
    uploaded = {"urdf": ("a.urdf", TWO_JOINT_URDF.encode(), "application/xml")}
    assert_detail(client.post("/v1/robot-models", files=uploaded), 413, "max_urdf_bytes")
    big = _zip({"meshes/part.stl": bytes(range(256)) * 64})
    assert len(big) > 4096
    assert_detail(
        client.post(
            "/v1/robot-models",
            data={"urdf": ONE_LINK_URDF},
            files={"archive": ("a.zip", big, "application/zip")},
        ),
        413,
        "max_archive_bytes",
    )
    assert_detail(
        client.post(
            "/v1/robot-models",
            json={"urdf": ONE_LINK_URDF, "archive_base64": base64.b64encode(big).decode()},
        ),
        413,
        "max_archive_bytes",
    )


def test_archive_entry_limit(client_factory: ClientFactory) -> None:
    client = client_factory(max_archive_entries=2)
    archive = _zip({f"m/{i}.stl": b"x" for i in range(3)})
    response = client.post(
        "/v1/robot-models",
        json={"urdf": MESH_URDF, "archive_base64": base64.b64encode(archive).decode()},
    )
    assert_detail(response, 422, "at most 2")


def test_reference_robot_registers(app_client: TestClient, reference_urdf: str) -> None:
    body = register(app_client, reference_urdf, base="planar")
    assert body["state_names"][:3] == ["base_x", "base_y", "base_theta"]
    assert body["joint_names"] == [f"joint{i}" for i in range(1, 8)]


def test_another_replica_serves_the_model_detail(client_factory: ClientFactory) -> None:
    first = client_factory()
    model_id = register(first, base="planar")["model_id"]
    second = client_factory()  # empty model cache: the detail loads the model from the database
    reply = second.get(f"/v1/robot-models/{model_id}")
    assert reply.status_code == 200, reply.text
    assert reply.json()["model_id"] == model_id
