"""API keys and roles: 401 without a valid key, 403 past a role or robot binding, every route."""

from __future__ import annotations

import re
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from tests.robots import TWO_JOINT_URDF
from trajcache.api.auth import POLICY, is_loopback
from trajcache.services.catalog.keys import Role, create_key, revoke_key


def _key(client: TestClient, role: str, robots: list[str] | None = None) -> str:
    ctx = ctx_of(client)
    with ctx.sessions() as session:
        _, secret = create_key(session=session, name=f"{role} key", role=role, robot_ids=robots)
    ctx.keys.clear()
    return secret


def _h(secret: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {secret}"}


@pytest.fixture
def secured(client_factory: ClientFactory) -> tuple[TestClient, dict[str, str]]:
    """An app with checks on, a model, robots r1 and r2, and a key of each role."""
    client = client_factory(auth_mode="on", auth_cache_ttl_s=0)
    keys = {
        "admin": _key(client, "admin"),
        "seeder": _key(client, "seeder"),
        "robot": _key(client, "robot", ["r1"]),
    }
    model_id = client.post(
        "/v1/robot-models", json={"urdf": TWO_JOINT_URDF}, headers=_h(keys["seeder"])
    ).json()["model_id"]
    for robot in ("r1", "r2"):
        reply = client.put(
            f"/v1/robots/{robot}", json={"model_id": model_id}, headers=_h(keys["admin"])
        )
        assert reply.status_code == 201, reply.text
    return client, keys


def test_no_key_wrong_key_and_revoked_key_are_401(
    secured: tuple[TestClient, dict[str, str]],
) -> None:
    client, keys = secured
    reply = client.get("/v1/robots/r1/scene")
    detail = assert_detail(reply, 401, "API key is required", "'API keys' section")
    assert "AUTH_MODE" not in detail and "off" not in detail  # not told to an unknown caller
    assert reply.headers["www-authenticate"] == "Bearer"
    assert_detail(client.get("/v1/robots/r1/scene", headers=_h("nonsense")), 401, "unknown")
    forged = keys["admin"][:-4] + "AAAA"
    assert_detail(client.get("/v1/robots/r1/scene", headers=_h(forged)), 401, "unknown")
    ok = client.get("/v1/robots/r1/scene", headers={"X-API-Key": keys["robot"]})
    assert ok.status_code == 200, ok.text

    ctx = ctx_of(client)
    with ctx.sessions() as session:
        revoke_key(session=session, key=keys["robot"].split("_")[1])
    revoked = client.get("/v1/robots/r1/scene", headers=_h(keys["robot"]))
    assert "AUTH_MODE" not in assert_detail(revoked, 401, "revoked", "README.md#api-keys")


def test_health_stays_open(secured: tuple[TestClient, dict[str, str]]) -> None:
    client, _ = secured
    assert client.get("/healthz").status_code == 200


def test_robot_key_is_bound_to_its_robots(secured: tuple[TestClient, dict[str, str]]) -> None:
    client, keys = secured
    robot = _h(keys["robot"])
    scene = {"objects": []}
    assert client.put("/v1/robots/r1/scene", json=scene, headers=robot).status_code == 200
    assert_detail(client.put("/v1/robots/r2/scene", json=scene, headers=robot), 403, "'r2'")
    assert_detail(client.get("/v1/robots/r2/scene", headers=robot), 403, "'r2'")
    body = {"start": [0, 0], "goal": [1, 0], "options": {"fallback": False}}
    assert client.post("/v1/robots/r1/plan", json=body, headers=robot).status_code == 200
    assert_detail(client.post("/v1/robots/r2/plan", json=body, headers=robot), 403, "'r2'")
    # The admin and nobody else may re-point a robot, even the robot itself.
    reply = client.put("/v1/robots/r1", json={"model_id": "x" * 64}, headers=robot)
    assert_detail(reply, 403, "robot key may not PUT")


def test_seeder_registers_models_but_cannot_plan_or_delete(
    secured: tuple[TestClient, dict[str, str]],
) -> None:
    client, keys = secured
    seeder = _h(keys["seeder"])
    body = {"start": [0, 0], "goal": [1, 0]}
    assert_detail(client.post("/v1/robots/r1/plan", json=body, headers=seeder), 403, "seeder")
    assert client.get("/v1/trajectories", headers=seeder).status_code == 200
    assert_detail(client.delete("/v1/trajectories/1", headers=seeder), 403, "admin only")


def test_a_403_names_the_path_as_requested(secured: tuple[TestClient, dict[str, str]]) -> None:
    client, keys = secured
    reply = client.get("/v1/stats", headers=_h(keys["seeder"]))
    assert_detail(reply, 403, "a seeder key may not GET /v1/stats (admin only)")
    reply = client.put("/v1/robots/r1", json={"model_id": "x" * 64}, headers=_h(keys["robot"]))
    assert_detail(reply, 403, "a robot key may not PUT /v1/robots/r1 ")


def _routes(client: TestClient) -> list[tuple[str, str]]:
    paths: dict[str, dict[str, Any]] = client.app.openapi()["paths"]  # type: ignore[attr-defined]
    return sorted(
        (method.upper(), path)
        for path, ops in paths.items()
        if path.startswith("/v1/")
        for method in ops
    )


@pytest.mark.parametrize("role", [r.value for r in Role])
def test_every_route_follows_the_policy_for_every_role(
    secured: tuple[TestClient, dict[str, str]], role: str
) -> None:
    client, keys = secured
    routes = _routes(client)
    assert len(routes) >= 10
    for method, path in routes:
        rule = POLICY.get((method, path[len("/v1") :]))
        allowed = role == "admin" or (rule is not None and Role(role) in rule.roles)
        for robot_id, own in (("r1", True), ("r2", False)):
            url = re.sub(r"\{robot_id\}", robot_id, path)
            url = re.sub(r"\{[a-z_]+\}", "999999", url)
            if role == "robot" and rule is not None and rule.own_robot and not own:
                expected_allowed = False
            else:
                expected_allowed = allowed
            reply = client.request(method, url, headers=_h(keys[role]), json={})
            denied = reply.status_code == 403
            assert reply.status_code != 401, (method, url, reply.text)
            assert denied != expected_allowed, (role, method, url, reply.status_code, reply.text)
            if "{robot_id}" not in path:
                break


def test_auto_mode_turns_on_with_the_first_key_or_a_public_bind(
    client_factory: ClientFactory,
) -> None:
    client = client_factory(auth_cache_ttl_s=0)
    assert client.get("/v1/robot-models").status_code == 200  # loopback, no keys: open
    secret = _key(client, "seeder")
    assert client.get("/v1/robot-models").status_code == 401
    assert client.get("/v1/robot-models", headers=_h(secret)).status_code == 200

    public = client_factory(host="0.0.0.0", auth_cache_ttl_s=0)
    assert_detail(public.get("/v1/robot-models"), 401, "API key is required")
    off = client_factory(host="0.0.0.0", auth_mode="off")
    register(off)


def test_auto_mode_stays_on_after_the_last_key_is_revoked(client_factory: ClientFactory) -> None:
    client = client_factory(auth_cache_ttl_s=0)
    secret = _key(client, "admin")
    assert client.get("/v1/stats", headers=_h(secret)).status_code == 200
    ctx = ctx_of(client)
    with ctx.sessions() as session:
        revoke_key(session=session, key=secret.split("_")[1])
    ctx.keys.clear()
    assert_detail(client.get("/v1/stats"), 401, "API key is required")
    assert_detail(client.get("/v1/stats", headers=_h(secret)), 401, "revoked")
    # Only the operator opens it again, explicitly.
    assert client_factory(auth_mode="off").get("/v1/stats").status_code == 200


def test_revoking_a_revoked_key_is_a_conflict(client_factory: ClientFactory) -> None:
    from trajcache.services.errors import ConflictError, NotFoundError

    client = client_factory()
    secret = _key(client, "seeder")
    prefix = secret.split("_")[1]
    with ctx_of(client).sessions() as session:
        first = revoke_key(session=session, key=prefix)
        assert first.revoked_at is not None
        with pytest.raises(ConflictError, match=rf"#{first.id} \({prefix}, 'seeder key'\) was"):
            revoke_key(session=session, key=str(first.id))
        with pytest.raises(NotFoundError, match="'nope' not found"):
            revoke_key(session=session, key="nope")


def test_is_loopback() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("10.0.0.5") and not is_loopback("")
    assert not is_loopback("example.org")


def test_key_validation() -> None:
    from trajcache.services.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="role 'root'"):
        create_key(session=None, name="x", role="root")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="must name the robot ids"):
        create_key(session=None, name="x", role="robot")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="only robot keys"):
        create_key(session=None, name="x", role="admin", robot_ids=["r1"])  # type: ignore[arg-type]
