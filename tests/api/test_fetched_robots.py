"""Each robot `trajcache robots fetch` writes registers through the API, by the very lines it
prints: the curl form and the Python client call name the same model."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from trajcache.cli import app
from trajcache.reference.example_robots import ROBOTS
from trajcache_client import NO_RETRY, Client


def _printed(out: Path, name: str) -> tuple[str, str]:
    """The curl and client lines `robots fetch NAME` prints."""
    result = CliRunner().invoke(app, ["robots", "fetch", name, "--out", str(out)])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    at = lines.index(f"# {name}")
    return lines[at + 1], lines[at + 2]


def _post_as_curl(client: TestClient, curl: str) -> Any:
    """POST the `-F` fields of a curl line: `key=@path` as an uploaded file, else as text."""
    words = shlex.split(curl)
    assert words[:2] == ["curl", "-s"]
    if words[2] == "-H":  # the key header, `X-API-Key: ${TRAJCACHE_API_KEY:-}`
        assert words[3].startswith("X-API-Key: ")
        words = words[:2] + words[4:]
    assert words[2].endswith("/v1/robot-models")
    fields = [words[i + 1] for i, word in enumerate(words) if word == "-F"]
    data, files = {}, {}
    for field in fields:
        key, _, value = field.partition("=")
        if value.startswith("@"):
            path = Path(value[1:])
            files[key] = (path.name, path.read_bytes())
        else:
            data[key] = value
    return client.post("/v1/robot-models", data=data, files=files)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_a_fetched_robot_registers_as_printed(
    app_client: TestClient, tmp_path: Path, name: str
) -> None:
    curl, call = _printed(tmp_path, name)
    response = _post_as_curl(app_client, curl)
    assert response.status_code == 201, response.text
    body = response.json()
    assert len(body["joint_names"]) >= 6
    assert body["name"] == name

    transport = app_client._transport  # the client library, in process
    with Client("http://testserver", retry=NO_RETRY, transport=transport) as client:
        model = eval(call, {"client": client, "Path": Path})
    assert model.model_id == body["model_id"]  # the same files, fields and so the same model
