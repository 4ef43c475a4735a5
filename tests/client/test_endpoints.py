"""Each endpoint is declared once (`_endpoints.Endpoints`) and is a typed method of both clients."""

from __future__ import annotations

import asyncio
import inspect
from pathlib import Path

import httpx
import mypy.api
import pytest

import trajcache_client as tc
from trajcache_client._endpoints import Endpoint, Endpoints

CLIENT = Path(__file__).resolve().parents[2] / "client"
DECLARED = sorted(n for n, v in vars(Endpoints).items() if isinstance(v, Endpoint))


@pytest.mark.parametrize("name", DECLARED)
def test_a_declared_endpoint_has_its_operations_signature_on_both_clients(name: str) -> None:
    build = vars(Endpoints)[name].build
    wanted = list(inspect.signature(build).parameters.values())
    for client in (tc.Client, tc.AsyncClient):
        method = getattr(client, name)
        assert list(inspect.signature(method).parameters.values())[1:] == wanted, client
        assert method.__doc__ == vars(Endpoints)[name].__doc__
    assert not inspect.iscoroutinefunction(getattr(tc.Client, name))
    assert inspect.iscoroutinefunction(getattr(tc.AsyncClient, name))


def _answering(body: bytes) -> httpx.MockTransport:
    return httpx.MockTransport(lambda request: httpx.Response(200, content=body))


def test_the_blocking_client_returns_and_the_asyncio_client_awaits_the_same_answer() -> None:
    body = (
        b'{"robot_id": "r1", "model_id": "m1", "kind": "real", "scene_version": 0,'
        b' "created_at": "2026-01-01T00:00:00Z", "updated_at": "2026-01-01T00:00:00Z"}'
    )
    with tc.Client(transport=_answering(body)) as client:
        robot = client.get_robot("r1")

    async def fetch() -> tc.Robot:
        async with tc.AsyncClient(transport=_answering(body)) as client:
            return await client.get_robot("r1")

    assert asyncio.run(fetch()) == robot and robot.robot_id == "r1"


def test_mypy_types_the_declared_methods(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A wrong argument is a type error, and each answer has its model's type."""
    (tmp_path / "use.py").write_text(
        "import trajcache_client as tc\n"
        "async def use(c: tc.Client, a: tc.AsyncClient) -> None:\n"
        "    reveal_type(c.get_robot('r'))\n"
        "    reveal_type(await a.list_models(limit=3))\n"
        "    c.get_robot(3)\n"
        "    await a.plan('r', [0.0], [1.0], bogus=1)\n"
    )
    monkeypatch.setenv("MYPYPATH", str(CLIENT))  # this checkout's client, not an installed one
    out, err, _ = mypy.api.run(
        [str(tmp_path / "use.py"), "--cache-dir", str(tmp_path / "cache"), "--config-file", ""]
    )
    out += err
    assert 'Revealed type is "trajcache_client._models.Robot"' in out, out
    assert "Page[trajcache_client._models.RobotModelSummary]" in out, out
    assert 'Argument 1 has incompatible type "int"; expected "str"' in out, out
    assert 'Unexpected keyword argument "bogus"' in out, out
