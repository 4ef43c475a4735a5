"""docker/ checked statically (no Docker engine here): services, ports, settings, commands."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml
from sqlalchemy.engine import make_url
from typer.testing import CliRunner

from trajcache.cli import app as cli_app
from trajcache.core.config import Settings

ROOT = Path(__file__).resolve().parents[1]
DOCKER = ROOT / "docker"
API_REPLICAS = {"api-1", "api-2"}
TRAJCACHE_SERVICES = {"migrate", "planner", *API_REPLICAS}


def _settings_env() -> dict[str, str]:
    prefix = str(Settings.model_config.get("env_prefix", ""))
    return {(f.alias or prefix + name).upper(): name for name, f in Settings.model_fields.items()}


@pytest.fixture(scope="module")
def compose() -> dict[str, Any]:
    loaded: dict[str, Any] = yaml.safe_load((DOCKER / "compose.yaml").read_text())
    return loaded


@pytest.fixture(scope="module")
def services(compose: dict[str, Any]) -> dict[str, dict[str, Any]]:
    found: dict[str, dict[str, Any]] = compose["services"]
    return found


def _environment(service: dict[str, Any]) -> dict[str, str]:
    env = service.get("environment") or {}
    if isinstance(env, list):
        env = dict(item.split("=", 1) for item in env)
    return {str(k): str(v) for k, v in env.items()}


def _published(service: dict[str, Any]) -> list[str]:
    return [str(p) for p in service.get("ports", [])]


def test_the_fleet_has_every_part(services: dict[str, dict[str, Any]]) -> None:
    assert set(services) == {"postgres", "redis", "proxy", "prometheus", *TRAJCACHE_SERVICES}
    assert services["postgres"]["image"].startswith("postgres:")
    assert services["redis"]["image"].startswith("redis:")
    assert services["proxy"]["image"].startswith("nginx:")
    assert services["prometheus"]["image"].startswith("prom/prometheus")
    for name in TRAJCACHE_SERVICES:
        assert services[name]["build"] == {"context": "..", "dockerfile": "docker/Dockerfile"}
    assert services["planner"]["deploy"]["replicas"] >= 1


def test_only_the_proxy_and_prometheus_are_published_on_loopback(
    services: dict[str, dict[str, Any]],
) -> None:
    published = {name: _published(s) for name, s in services.items() if s.get("ports")}
    assert published == {"proxy": ["127.0.0.1:8000:80"], "prometheus": ["127.0.0.1:9090:9090"]}
    nginx = (DOCKER / "nginx.conf").read_text()
    assert re.search(r"^\s*listen 80;", nginx, re.M)


def test_every_trajcache_variable_is_a_valid_setting(services: dict[str, dict[str, Any]]) -> None:
    known = _settings_env()
    for name in TRAJCACHE_SERVICES:
        env = _environment(services[name])
        ours = {k: v for k, v in env.items() if k.startswith("TRAJCACHE_")}
        assert ours, f"{name} sets no TRAJCACHE_* variable"
        unknown = set(ours) - set(known)
        assert not unknown, f"{name} sets {sorted(unknown)}, which are not Settings fields"
        settings = Settings(**{known[k]: v for k, v in ours.items()})  # the values parse too
        assert settings.worker_backend == "celery"
        assert settings.database_url.startswith("postgresql+psycopg://")


def test_the_services_share_one_database_and_broker(services: dict[str, dict[str, Any]]) -> None:
    pg = _environment(services["postgres"])
    for name in TRAJCACHE_SERVICES:
        env = _environment(services[name])
        url = make_url(env["TRAJCACHE_DATABASE_URL"])
        assert (url.host, url.port, url.database) == ("postgres", 5432, pg["POSTGRES_DB"])
        assert (url.username, url.password) == (pg["POSTGRES_USER"], pg["POSTGRES_PASSWORD"])
        assert env["TRAJCACHE_CELERY_BROKER_URL"].startswith("redis://redis:6379/")


def _check_cli(args: list[str]) -> str:
    """The subcommand `args` name; the CLI refuses unknown commands and options before --help."""
    result = CliRunner().invoke(cli_app, [*args, "--help"])
    assert result.exit_code == 0, f"`trajcache {' '.join(args)}`: {result.output}"
    return args[0]


def test_commands_are_real_cli_commands(services: dict[str, dict[str, Any]]) -> None:
    used = {}
    for name in TRAJCACHE_SERVICES:
        command = services[name]["command"]
        assert command[0] == "trajcache", f"{name} runs {command}"
        used[name] = _check_cli(command[1:])
    assert used == {"migrate": "migrate", "planner": "worker", "api-1": "serve", "api-2": "serve"}
    with pytest.raises(AssertionError):
        _check_cli(["serve", "--no-such-option"])
    with pytest.raises(AssertionError):
        _check_cli(["no-such-command"])


def test_replicas_wait_for_the_migration_and_are_behind_the_proxy(
    services: dict[str, dict[str, Any]],
) -> None:
    assert services["migrate"]["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert services["migrate"]["restart"] == "no"
    nginx = (DOCKER / "nginx.conf").read_text()
    upstream = set(re.findall(r"^\s*server\s+([\w.-]+:\d+)", nginx, re.M))
    targets = set()
    for name in API_REPLICAS:
        api = services[name]
        assert "--no-migrate" in api["command"]
        condition = api["depends_on"]["migrate"]["condition"]
        assert condition == "service_completed_successfully"
        port = _environment(api)["TRAJCACHE_PORT"]
        assert _environment(api)["TRAJCACHE_HOST"] == "0.0.0.0"
        targets.add(f"{name}:{port}")
        assert services["proxy"]["depends_on"][name]["condition"] == "service_healthy"
    assert upstream == targets
    for name in ("migrate", "planner"):
        assert services[name]["healthcheck"] == {"disable": True}  # they serve no HTTP


def test_prometheus_scrapes_metrics_on_every_replica(services: dict[str, dict[str, Any]]) -> None:
    config = yaml.safe_load((DOCKER / "prometheus.yml").read_text())
    (job,) = config["scrape_configs"]
    assert job["metrics_path"] == "/metrics"
    targets = {t for group in job["static_configs"] for t in group["targets"]}
    expected = {f"{n}:{_environment(services[n])['TRAJCACHE_PORT']}" for n in API_REPLICAS}
    assert targets == expected
    mounted = services["prometheus"]["volumes"][0].split(":")
    assert (DOCKER / mounted[0]).resolve() == DOCKER / "prometheus.yml"
    assert mounted[1] == "/etc/prometheus/prometheus.yml"


def _dockerfile() -> list[tuple[str, str]]:
    text = (DOCKER / "Dockerfile").read_text().replace("\\\n", " ")
    lines = [line.strip() for line in text.splitlines()]
    return [
        (line.split(None, 1)[0].upper(), line.split(None, 1)[1])
        for line in lines
        if line and not line.startswith("#")
    ]


def test_the_image_is_slim_non_root_and_checks_its_health() -> None:
    steps = _dockerfile()
    froms = [arg for op, arg in steps if op == "FROM"]
    assert froms and all(re.fullmatch(r"python:3\.\d+-slim", f) for f in froms)
    users = [arg for op, arg in steps if op == "USER"]
    assert users and users[-1] not in {"root", "0"}
    (health,) = [arg for op, arg in steps if op == "HEALTHCHECK"]
    assert "/healthz" in health and "TRAJCACHE_PORT" in health
    copied = " ".join(arg for op, arg in steps if op == "COPY")
    for needed in ("pyproject.toml", "service", "client"):  # the migrations are in service/
        assert needed in copied


def test_the_image_installs_with_the_readme_command() -> None:
    runs = [arg for op, arg in _dockerfile() if op == "RUN"]
    installs = [run for run in runs if "pip install" in run]
    assert installs == ["pip install ."]  # not editable: the package brings its migrations
    readme = (ROOT / "README.md").read_text()
    commands = {
        " ".join(line.split("#")[0].split())
        for block in re.findall(r"```sh\n(.*?)```", readme, re.S)
        for line in block.splitlines()
    }
    assert installs[0] in commands
