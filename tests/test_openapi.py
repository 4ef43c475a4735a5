"""openapi/openapi.json is the app's document, and every operation in it is fully described."""

from __future__ import annotations

import functools
import json
import re
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from trajcache.cli import app as cli
from trajcache.cli.docs import openapi_document, openapi_text
from trajcache.core.config import MAX_PAGE_SIZE
from trajcache.services.errors import InvalidInputError
from trajcache.services.stats.window import WINDOW_PATTERN, parse_window

ROOT = Path(__file__).resolve().parents[1]
DOCUMENT = ROOT / "openapi" / "openapi.json"
# Answered from the process alone while it runs: these have no error to declare.
PROCESS_ONLY = {("get", "/healthz"), ("get", "/metrics")}


@functools.cache
def _document() -> dict[str, Any]:
    return openapi_document()


def _operations() -> list[tuple[str, str, dict[str, Any]]]:
    paths = _document()["paths"]
    return [(method, path, op) for path, ops in paths.items() for method, op in ops.items()]


def _cases() -> list[Any]:
    return [pytest.param(m, p, op, id=f"{m.upper()} {p}") for m, p, op in _operations()]


def _resolve(document: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    ref = schema.get("$ref")
    if ref is None:
        return schema
    name = ref.rsplit("/", 1)[-1]
    resolved: dict[str, Any] = document["components"]["schemas"][name]
    return resolved


def _has_example(document: dict[str, Any], media: dict[str, Any]) -> bool:
    if "example" in media or "examples" in media:
        return True
    schema = _resolve(document, media.get("schema", {}))
    if schema.get("type") == "array":  # a list of models: the items' examples show it
        schema = _resolve(document, schema.get("items", {}))
    return "examples" in schema


def test_the_committed_document_is_the_apps() -> None:
    committed = DOCUMENT.read_text(encoding="utf-8")
    assert committed == openapi_text(), (
        "openapi/openapi.json differs from the app; regenerate it with `trajcache openapi`"
    )


def test_the_document_covers_the_core_contract() -> None:
    operations = {(m.upper(), p) for m, p, _ in _operations()}
    assert operations >= {
        ("POST", "/v1/robot-models"),
        ("PUT", "/v1/robots/{robot_id}"),
        ("PUT", "/v1/robots/{robot_id}/scene"),
        ("PATCH", "/v1/robots/{robot_id}/scene"),
        ("GET", "/v1/robots/{robot_id}/scene"),
        ("POST", "/v1/robots/{robot_id}/plan"),
        ("GET", "/v1/trajectories"),
        ("GET", "/v1/trajectories/{trajectory_id}"),
        ("DELETE", "/v1/trajectories/{trajectory_id}"),
        ("GET", "/healthz"),
        ("GET", "/readyz"),
    }


@pytest.mark.parametrize(("method", "path", "op"), _cases())
def test_every_operation_has_a_summary_description_and_examples(
    method: str, path: str, op: dict[str, Any]
) -> None:
    document = _document()
    assert op.get("summary") and op.get("description"), f"{method} {path}"
    for media_type, media in op.get("requestBody", {}).get("content", {}).items():
        assert _has_example(document, media), f"{method} {path}: {media_type} body has no example"
    successes = {code: r for code, r in op["responses"].items() if code.startswith("2")}
    assert successes, f"{method} {path} declares no success response"
    for code, response in successes.items():
        for media in response.get("content", {}).values():
            assert _has_example(document, media), f"{method} {path}: {code} has no example"


@pytest.mark.parametrize(("method", "path", "op"), _cases())
def test_every_operation_declares_its_errors_with_the_error_body(
    method: str, path: str, op: dict[str, Any]
) -> None:
    errors = {code: r for code, r in op["responses"].items() if code[0] in "45"}
    if (method, path) in PROCESS_ONLY:
        assert errors == {}
        return
    assert errors, f"{method} {path} declares no error response"
    for code, response in errors.items():
        media = response["content"]["application/json"]
        assert media["schema"] == {"$ref": "#/components/schemas/ErrorOut"}, f"{path} {code}"
        assert isinstance(media["example"]["detail"], str) and response["description"]


def _query_parameters(name: str) -> list[tuple[str, dict[str, Any]]]:
    return [
        (f"{method.upper()} {path}", parameter["schema"])
        for method, path, op in _operations()
        for parameter in op.get("parameters", [])
        if parameter["in"] == "query" and parameter["name"] == name
    ]


def test_every_page_size_states_its_maximum() -> None:
    limits = dict(_query_parameters("limit"))
    pages = {"GET /v1/robot-models", "GET /v1/trajectories", "GET /v1/seed-jobs"}
    assert pages | {"GET /v1/plan-events", "GET /v1/stats/top-trajectories"} == set(limits)
    for operation, schema in limits.items():
        (bound,) = [s for s in schema.get("anyOf", [schema]) if s.get("type") == "integer"]
        assert bound["minimum"] == 1, operation
        top = operation == "GET /v1/stats/top-trajectories"
        assert bound["maximum"] == (100 if top else MAX_PAGE_SIZE), operation


WINDOWS = ["30m", "24h", "7d", "1m", "366d", " 5 m ", "0m", "999999d"]
NOT_WINDOWS = ["2w", "soon", "30", "h", "1.5h", "-1h", "1000000m", "30m\n", "\t30m", "٣m", ""]


def test_the_stats_window_states_the_parsers_pattern() -> None:
    ((_, schema),) = _query_parameters("window")
    pattern = re.compile(schema["pattern"])  # ECMA and Python read this one alike
    assert schema["pattern"] == WINDOW_PATTERN
    for text in WINDOWS:
        assert pattern.fullmatch(text), text
    for text in NOT_WINDOWS:
        assert not pattern.fullmatch(text), text
        with pytest.raises(InvalidInputError):
            parse_window(text)
    assert [parse_window(t) for t in ("30m", " 5 m ", "366d")] == [1800, 300, 366 * 86400]


def test_the_openapi_command_writes_and_checks(tmp_path: Path) -> None:
    runner = CliRunner()
    target = tmp_path / "api" / "openapi.json"
    stale = runner.invoke(cli, ["openapi", "--out", str(target), "--check"])
    assert stale.exit_code == 1 and "trajcache openapi" in stale.output
    written = runner.invoke(cli, ["openapi", "--out", str(target)])
    assert written.exit_code == 0, written.output
    assert json.loads(target.read_text()) == openapi_document()
    assert runner.invoke(cli, ["openapi", "--out", str(target), "--check"]).exit_code == 0
    target.write_text("{}\n")
    assert runner.invoke(cli, ["openapi", "--out", str(target), "--check"]).exit_code == 1


def test_the_document_does_not_depend_on_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_MAX_PAGE_SIZE", "7")
    monkeypatch.setenv("TRAJCACHE_DATABASE_URL", "postgresql://elsewhere/db")
    assert openapi_text() == DOCUMENT.read_text(encoding="utf-8")
