"""/v1/admin: prune (dry run, apply, two replicas), export and import through the real app."""

from __future__ import annotations

import gzip
import json
import threading
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.conftest import ClientFactory, assert_detail, ctx_of, register
from trajcache.core.config import Settings
from trajcache.main import create_app
from trajcache.services.catalog.keys import create_key

QUIET = {"worker_backend": "none"}


def store(client: TestClient, model_id: str, count: int) -> list[int]:
    ids = []
    for k in range(count):
        states = [[0.0, 0.0], [0.01 * (k + 1), 0.5]]
        response = client.post("/v1/trajectories", json={"model_id": model_id, "states": states})
        assert response.status_code == 201, response.text
        ids.append(int(response.json()["trajectory_id"]))
    return ids


def listed(client: TestClient) -> list[int]:
    page = client.get("/v1/trajectories", params={"limit": 1000}).json()
    return [t["trajectory_id"] for t in page["items"]]


def test_prune_is_a_dry_run_unless_asked(client_factory: ClientFactory) -> None:
    client = client_factory(**QUIET, cache_max_per_model=3)
    model_id = register(client)["model_id"]
    ids = store(client, model_id, 5)  # never used: the oldest go first
    dry = client.post("/v1/admin/prune", json={})
    assert dry.status_code == 200, dry.text
    body = dry.json()
    assert (body["dry_run"], body["policy"], body["cap"], body["deleted"]) == (True, "lru", 3, 2)
    assert body["models"] == [
        {"model_id": model_id, "trajectories": 5, "deleted": 2, "ids": ids[:2]}
    ]
    assert listed(client) == ids

    applied = client.post("/v1/admin/prune", json={"dry_run": False}).json()
    assert (applied["dry_run"], applied["deleted"]) == (False, 2)
    assert listed(client) == ids[2:]
    assert_detail(client.get(f"/v1/trajectories/{ids[0]}"), 404)
    again = client.post("/v1/admin/prune", json={"dry_run": False}).json()
    assert again["deleted"] == 0 and again["models"] == []

    capped = client.post(
        "/v1/admin/prune", json={"dry_run": False, "cap": 1, "policy": "least_hit"}
    )
    assert capped.json()["deleted"] == 2 and listed(client) == ids[4:]


def test_prune_input_errors(client_factory: ClientFactory) -> None:
    client = client_factory(**QUIET)  # no cap configured
    register(client)
    assert_detail(client.post("/v1/admin/prune", json={}), 422, "no cap")
    assert_detail(client.post("/v1/admin/prune", json={"cap": 0}), 422, "body.cap")
    assert_detail(
        client.post("/v1/admin/prune", json={"cap": 1, "policy": "fifo"}), 422, "body.policy"
    )
    assert_detail(
        client.post("/v1/admin/prune", json={"cap": 1, "dryrun": True}), 422, "body.dryrun"
    )
    assert_detail(
        client.post("/v1/admin/prune", json={"cap": 1, "model_id": "f" * 64}), 404, "robot model"
    )


def test_two_replicas_prune_at_once(database_url: str) -> None:
    settings = Settings(database_url=database_url, worker_backend="none", worker_prestart=False)
    with TestClient(create_app(settings)) as a, TestClient(create_app(settings)) as b:
        model_id = register(a)["model_id"]
        ids = store(a, model_id, 12)
        answers: list[Any] = []
        barrier = threading.Barrier(2)

        def prune(client: TestClient) -> None:
            barrier.wait()
            answers.append(client.post("/v1/admin/prune", json={"dry_run": False, "cap": 4}))

        threads = [threading.Thread(target=prune, args=(c,)) for c in (a, b)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert [r.status_code for r in answers] == [200, 200]
        assert sum(r.json()["deleted"] for r in answers) == 8
        assert listed(a) == listed(b) == ids[8:]
        for client in (a, b):  # each replica's index dropped the evicted ones
            ctx = ctx_of(client)
            with ctx.sessions() as session:
                from trajcache.services.catalog.models import get_model

                model = get_model(session=session, registry=ctx.models, model_id=model_id)
                index = ctx.indexes.index(session, model)
            assert sorted(i for i in ids if i in index) == ids[8:]


def test_export_then_import_into_another_database(
    client_factory: ClientFactory, tmp_path: Path
) -> None:
    source_settings = Settings(database_url=f"sqlite:///{tmp_path / 'src.db'}", **QUIET)  # type: ignore[arg-type]
    with TestClient(create_app(source_settings)) as source:
        model_id = register(source)["model_id"]
        store(source, model_id, 3)
        exported = source.get("/v1/admin/export", params={"source": "real"})
        assert exported.status_code == 200
        assert exported.headers["content-type"].startswith("application/x-ndjson")
        assert source.get("/v1/admin/export", params={"source": "sim"}).text.count("\n") == 2
        assert_detail(source.get("/v1/admin/export", params={"model_id": "nope"}), 404)
        assert_detail(source.get("/v1/admin/export", params={"source": "dream"}), 422, "source")
    lines = exported.text.splitlines()
    assert [json.loads(line)["type"] for line in lines] == ["header", "model"] + [
        "trajectory"
    ] * 3 + ["end"]

    target = client_factory(**QUIET)
    first = target.post(
        "/v1/admin/import",
        content=gzip.compress(exported.content),
        headers={"content-type": "application/x-ndjson"},
    )
    assert first.status_code == 200, first.text
    assert {k: first.json()[k] for k in ("inserted", "duplicates", "models_created")} == {
        "inserted": 3,
        "duplicates": 0,
        "models_created": 1,
    }
    second = target.post("/v1/admin/import", content=exported.content, params={"source": "import"})
    assert (second.json()["inserted"], second.json()["duplicates"]) == (0, 3)
    assert target.get("/v1/trajectories").json()["total"] == 3

    *written, end = exported.content.splitlines(keepends=True)
    short = b'{"type": "trajectory", "model_id": "%s", "states": [[0]]}\n' % model_id.encode()
    broken = b"".join([*written, short, end])
    report = target.post("/v1/admin/import", content=broken).json()
    assert report["rejected_count"] == 1
    assert (
        report["rejected"][0]["line"] == 6
        and "at least 2 states" in report["rejected"][0]["reason"]
    )
    assert_detail(
        target.post("/v1/admin/import", content=b'{"type": "header", "format": "x", "version": 1}'),
        422,
        "not a trajcache export",
    )
    assert_detail(target.post("/v1/admin/import", content=b"\x1f\x8bnot gzip"), 422, "gzip")
    assert_detail(target.post("/v1/admin/import", content=b"\xff\xfe"), 422, "UTF-8")


def exported_export(tmp_path: Path) -> bytes:
    """An export of one model and three trajectories, from a database of its own."""
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'src.db'}", **QUIET)  # type: ignore[arg-type]
    with TestClient(create_app(settings)) as source:
        store(source, register(source)["model_id"], 3)
        return source.get("/v1/admin/export").content


def assert_nothing_imported(client: TestClient) -> None:
    assert client.get("/v1/trajectories").json()["total"] == 0
    assert client.get("/v1/robot-models").json()["total"] == 0


def test_a_line_that_is_not_json_refuses_the_whole_import(
    client_factory: ClientFactory, tmp_path: Path
) -> None:
    header, model, trajectory = exported_export(tmp_path).splitlines()[:3]
    good = json.loads(trajectory)
    lines = [header, model]
    for k in range(497):  # lines 3-499; one transaction, whatever the batch size once was
        record = {**good, "states": [[0.0, 0.0], [0.001 * (k + 1), 0.5]], "content_hash": None}
        lines.append(json.dumps(record).encode())
    body = b"\n".join([*lines, b'{"type": "trajectory", "model_id": '])
    target = client_factory(**QUIET)
    assert_detail(target.post("/v1/admin/import", content=body), 422, "line 500: not JSON")
    assert_nothing_imported(target)
    end = b'{"type": "end", "trajectories": 497}'
    response = target.post("/v1/admin/import", content=b"\n".join([*lines, end]))
    assert response.json()["inserted"] == 497, response.text


def test_import_refuses_corrupt_truncated_or_empty_bodies(
    client_factory: ClientFactory, tmp_path: Path
) -> None:
    exported = exported_export(tmp_path)
    packed = gzip.compress(exported)
    target = client_factory(**QUIET)

    def refused(body: bytes, *needles: str) -> None:
        assert_detail(target.post("/v1/admin/import", content=body), 422, *needles)
        assert_nothing_imported(target)

    half = len(packed) // 2
    refused(packed[:half], f"gzip stream truncated after {half} bytes")
    refused(packed[:-4], f"gzip stream truncated after {len(packed) - 4} bytes")
    refused(packed + b"trailing", "not valid gzip", f"byte {len(packed) + 1}")
    refused(packed[:-8] + bytes(8), "not valid gzip", "incorrect data check")
    refused(exported + b"\xff\xfe\n", "line 7: not UTF-8 text (byte 1 of the line)")
    refused(b"", "empty body: nothing to import")
    refused(b"\n \r\n", "empty body: nothing to import")
    refused(gzip.compress(b""), "empty body: nothing to import")

    lines = exported.splitlines(keepends=True)
    members = gzip.compress(b"".join(lines[:3])) + gzip.compress(b"".join(lines[3:]))
    whole = target.post("/v1/admin/import", content=members)  # as `cat a.gz b.gz` writes
    assert (whole.status_code, whole.json()["inserted"]) == (200, 3), whole.text


def test_import_body_is_bounded(client_factory: ClientFactory) -> None:
    client = client_factory(**QUIET, max_body_bytes=1000)
    assert_detail(client.post("/v1/admin/import", content=b"\n" * 1001), 413, "max_body_bytes=1000")
    bomb = gzip.compress(b"\n" * 100_000)
    assert len(bomb) < 1000
    assert_detail(client.post("/v1/admin/import", content=bomb), 413, "unpacked")


@pytest.mark.parametrize(("role", "status"), [("seeder", 403), ("admin", 200)])
def test_admin_routes_are_admin_only(client_factory: ClientFactory, role: str, status: int) -> None:
    client = client_factory(**QUIET, auth_mode="on", auth_cache_ttl_s=0)
    ctx = ctx_of(client)
    with ctx.sessions() as session:
        _, secret = create_key(session=session, name="k", role=role)
    headers = {"Authorization": f"Bearer {secret}"}
    response = client.post("/v1/admin/prune", json={"cap": 5}, headers=headers)
    assert response.status_code == status, response.text
    assert client.get("/v1/admin/export", headers=headers).status_code == status
