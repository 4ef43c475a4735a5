"""Cartesian paths through export and import (format version 3), on SQLite and PostgreSQL: a
round trip serves the imported path from the cache only once it is proven in the target robot's
scene; a path whose states leave its lines is stored as data but never served; a failing write
leaves nothing imported."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, ctx_of
from tests.api.test_cartesian import LINK, approach, cartesian, native, panda_fk  # noqa: F401
from tests.api.test_real_robots import READY, _register, _robot
from trajcache.core.config import Settings
from trajcache.db.cartesian import CartesianPathRow
from trajcache.db.models import RobotModel, Trajectory
from trajcache.main import create_app
from trajcache.reference.example_robots import ROBOTS
from trajcache.services.maintenance.cartesian_transfer import CartesianWriter
from trajcache.services.maintenance.importer import import_lines

QUIET = {"worker_backend": "none"}


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory, panda_fk: Any) -> list[dict[str, Any]]:  # noqa: F811
    """The export of a database holding one computed Cartesian path and one trajectory."""
    url = f"sqlite:///{tmp_path_factory.mktemp('source') / 'src.db'}"
    with TestClient(create_app(Settings(database_url=url, **QUIET))) as source:  # type: ignore[arg-type]
        model_id = _register(source, ROBOTS["panda"])["model_id"]
        robot = _robot(source, model_id, "panda")
        assert source.put(f"/v1/robots/{robot}/scene", json={"objects": []}).status_code == 200
        reply = cartesian(source, robot, native(approach(panda_fk)[1]))
        assert reply.json()["path_id"] is not None, reply.text
        stored = source.post(
            "/v1/trajectories", json={"model_id": model_id, "states": [READY, [*READY[:6], 0.5]]}
        )
        assert stored.status_code == 201, stored.text
        text = source.get("/v1/admin/export").text
    return [json.loads(line) for line in text.splitlines()]


def body(records: list[dict[str, Any]]) -> bytes:
    return "".join(json.dumps(r) + "\n" for r in records).encode()


@pytest.fixture
def target(client_factory: ClientFactory) -> TestClient:
    return client_factory(**QUIET)


def scene(client: TestClient, exported: list[dict[str, Any]], objects: list[Any]) -> None:
    """The robot `panda` of the imported model, in a scene of `objects`."""
    _robot(client, next(r["model_id"] for r in exported if r["type"] == "model"), "panda")
    assert client.put("/v1/robots/panda/scene", json={"objects": objects}).status_code == 200


def test_the_export_carries_the_path_after_its_model(exported: list[dict[str, Any]]) -> None:
    kinds = [r["type"] for r in exported]
    assert kinds == ["header", "model", "trajectory", "cartesian_path", "end"]
    assert exported[0]["version"] == 3
    assert exported[-1] == {"type": "end", "trajectories": 1, "cartesian_paths": 1}
    path = exported[3]
    assert path["link"] == LINK and path["states"][0] == path["start"] == pytest.approx(READY)
    assert len(path["line_of"]) == len(path["states"]) == 11


def test_a_round_trip_serves_the_path_only_where_it_is_proven(
    target: TestClient,
    exported: list[dict[str, Any]],
    panda_fk: Any,  # noqa: F811
) -> None:
    first = target.post("/v1/admin/import", content=body(exported)).json()
    assert (first["inserted"], first["cartesian_inserted"], first["rejected_count"]) == (1, 1, 0)
    again = target.post("/v1/admin/import", content=body(exported)).json()
    assert (again["cartesian_inserted"], again["cartesian_duplicates"]) == (0, 1)
    pose, waypoint = approach(panda_fk)
    scene(target, exported, [])
    served = cartesian(target, "panda", native(waypoint)).json()
    assert (served["source"], served["fraction"]) == ("cache", 1.0)
    assert served["states"] == exported[3]["states"]
    block = pose[:3, 3] + 0.17 * pose[:3, 2]  # on the approach line, past the fingertips
    box = {
        "id": "crate",
        "type": "box",
        "size": [0.1, 0.1, 0.02],
        "pose": {"position": block.tolist()},
    }
    scene(target, exported, [box])
    blocked = cartesian(target, "panda", native(waypoint)).json()
    assert blocked["source"] == "computed" and blocked["fraction"] < 1.0
    assert blocked["status"] in ("collision", "too_close")


def test_states_that_leave_their_lines_are_never_served(
    target: TestClient,
    exported: list[dict[str, Any]],
    panda_fk: Any,  # noqa: F811
) -> None:
    forged = dict(exported[3])
    states = [list(s) for s in forged["states"]]
    states[5][3] += 0.05  # within the joint's limits, 4 cm off the line
    forged["states"] = states
    report = target.post("/v1/admin/import", content=body([*exported[:3], forged, exported[-1]]))
    assert report.json()["cartesian_inserted"] == 1  # data that fits the model
    scene(target, exported, [])
    answer = cartesian(target, "panda", native(approach(panda_fk)[1])).json()
    assert (answer["source"], answer["fraction"]) == ("computed", 1.0)
    assert answer["states"][5] != states[5]


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"link": "nowhere"}, "not a link of model"),
        ({"params": "z" * 64}, "64 hex digits"),
        ({"start": [0.0] * 7}, "first state must be the start"),
        ({"line_of": [0] * 10}, "one integer a state"),
        ({"line_of": [0] * 10 + [1]}, "line_of names line 1 of 1"),
        ({"waypoints": [[0.3, 0.0, 0.5, 0.0, 0.0, 0.0, 2.0]]}, "not a unit one"),
        ({"states": [[9.0] * 7, [9.0] * 7], "start": [9.0] * 7}, "out of joint limits"),
    ],
)
def test_a_path_that_does_not_fit_its_model_is_rejected_with_its_reason(
    target: TestClient, exported: list[dict[str, Any]], change: dict[str, Any], reason: str
) -> None:
    broken = {**exported[3], **change}
    report = target.post("/v1/admin/import", content=body([*exported[:3], broken, exported[-1]]))
    answer = report.json()
    assert (answer["inserted"], answer["cartesian_inserted"], answer["rejected_count"]) == (1, 0, 1)
    assert answer["rejected"][0]["line"] == 4 and reason in answer["rejected"][0]["reason"]


def test_a_failing_write_leaves_nothing_half_imported(
    target: TestClient, exported: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    def failing_flush(self: CartesianWriter) -> None:
        raise RuntimeError("the disk is full")

    monkeypatch.setattr(CartesianWriter, "flush", failing_flush)
    ctx = ctx_of(target)
    lines = [json.dumps(r) for r in exported]
    with ctx.sessions() as session, pytest.raises(RuntimeError, match="disk is full"):
        import_lines(session=session, registry=ctx.models, settings=ctx.settings, lines=lines)
    with ctx.sessions() as session:
        for table in (CartesianPathRow, Trajectory):
            assert session.scalar(sa.select(sa.func.count()).select_from(table)) == 0
        models = session.scalar(sa.select(sa.func.count()).select_from(RobotModel))
    assert models == 0


def test_an_export_of_the_previous_version_still_imports(
    target: TestClient, exported: list[dict[str, Any]]
) -> None:
    header = {**exported[0], "version": 2}
    end = {"type": "end", "trajectories": 1}
    answer = target.post("/v1/admin/import", content=body([header, *exported[1:3], end])).json()
    assert (answer["inserted"], answer["cartesian_inserted"], answer["rejected_count"]) == (1, 0, 0)


def test_an_export_filtered_by_source_carries_no_paths(
    tmp_path: Path,
    panda_fk: Any,  # noqa: F811
) -> None:
    url = f"sqlite:///{tmp_path / 'src.db'}"
    with TestClient(create_app(Settings(database_url=url, **QUIET))) as source:  # type: ignore[arg-type]
        robot = _robot(source, _register(source, ROBOTS["panda"])["model_id"], "panda")
        assert source.put(f"/v1/robots/{robot}/scene", json={"objects": []}).status_code == 200
        assert cartesian(source, robot, native(approach(panda_fk)[1])).status_code == 200
        text = source.get("/v1/admin/export", params={"source": "planner"}).text
    assert [json.loads(line)["type"] for line in text.splitlines()] == ["header", "end"]
