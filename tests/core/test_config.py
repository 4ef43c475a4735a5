"""Settings: environment variables, URL normalisation, validation."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError

from trajcache.core.config import Settings, get_settings


@pytest.fixture(autouse=True)
def clean_env(monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    for name in list(os.environ):
        if name.startswith("TRAJCACHE_"):
            monkeypatch.delenv(name)
    get_settings.cache_clear()


def test_defaults() -> None:
    settings = Settings()
    data_dir = Path.home() / ".local" / "share" / "trajcache"
    if sys.platform == "linux" and "XDG_DATA_HOME" not in os.environ:
        assert settings.data_dir == data_dir
    assert settings.database_url == f"sqlite:///{settings.data_dir}/trajcache.db"
    assert (settings.lookup_threshold, settings.max_candidates) == (0.2, 3)
    assert (settings.step_position_m, settings.step_joint_rad) == (0.04, 0.035)
    assert settings.worker_backend == "local"
    assert settings.max_body_bytes == 16 * 1024 * 1024
    assert settings.auth_mode == "auto"


def test_every_field_is_described() -> None:
    missing = [name for name, field in Settings.model_fields.items() if not field.description]
    assert missing == []


def test_environment_variables_are_read(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_LOOKUP_THRESHOLD", "0.3")
    monkeypatch.setenv("TRAJCACHE_WORKER_BACKEND", "celery")
    monkeypatch.setenv("TRAJCACHE_CERTIFIED_VALIDATION", "false")
    monkeypatch.setenv("TRAJCACHE_LOG_LEVEL", "DEBUG")
    settings = Settings()
    assert settings.lookup_threshold == 0.3
    assert settings.worker_backend == "celery"
    assert settings.certified_validation is False
    assert settings.log_level == "debug"


def test_get_settings_is_cached(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_PORT", "9001")
    first = get_settings()
    monkeypatch.setenv("TRAJCACHE_PORT", "9002")
    assert get_settings() is first and first.port == 9001


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ("postgresql://u@db:5432/t", "postgresql+psycopg://u@db:5432/t"),
        ("postgres://u@db/t", "postgresql+psycopg://u@db/t"),
        ("postgresql+psycopg://u@db/t", "postgresql+psycopg://u@db/t"),
        ("sqlite:////var/lib/trajcache.db", "sqlite:////var/lib/trajcache.db"),
    ],
)
def test_database_url_normalisation(
    monkeypatch: pytest.MonkeyPatch, given: str, expected: str
) -> None:
    monkeypatch.setenv("TRAJCACHE_DATABASE_URL", given)
    assert Settings().database_url == expected


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ("sqlite:///trajcache.db", "sqlite:////srv/tc/trajcache.db"),
        ("sqlite:///./caches/a.db?timeout=5", "sqlite:////srv/tc/caches/a.db?timeout=5"),
        ("sqlite:////var/lib/trajcache.db", "sqlite:////var/lib/trajcache.db"),
        ("sqlite://", "sqlite://"),
        ("sqlite:///:memory:", "sqlite:///:memory:"),
        ("postgresql://u@db/t", "postgresql+psycopg://u@db/t"),
    ],
)
def test_a_relative_sqlite_path_is_in_the_data_dir_wherever_the_command_runs(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, given: str, expected: str
) -> None:
    monkeypatch.setenv("TRAJCACHE_DATA_DIR", "/srv/tc")
    monkeypatch.setenv("TRAJCACHE_DATABASE_URL", given)
    monkeypatch.chdir(tmp_path)
    assert Settings().database_url == expected
    assert Settings(database_url=given).database_url == expected


def test_the_data_dir_expands_the_home_directory(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_DATA_DIR", "~/tc")
    assert Settings().data_dir == Path.home() / "tc"


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("data_dir", "relative/dir"),
        ("database_url", "not a url"),
        ("lookup_threshold", "0"),
        ("lookup_threshold", "-0.1"),
        ("lookup_threshold", "0.6"),  # above lookup_threshold_max
        ("max_candidates", "0"),
        ("max_candidates", "11"),  # above max_candidates_limit
        ("worker_processes", "0"),
        ("step_joint_rad", "0"),
        ("plan_budget_s", "31"),
        ("index_sync_interval_s", "-1"),
        ("port", "70000"),
        ("worker_backend", "threads"),
        ("auth_mode", "maybe"),
        ("log_level", "loud"),
        ("database_url", " "),
        ("max_page_size", "0"),
        ("max_page_size", "1001"),  # above the page size the API document states
        ("lookup_threshold", "nan"),
    ],
)
def test_invalid_values_are_rejected(
    monkeypatch: pytest.MonkeyPatch, name: str, value: str
) -> None:
    monkeypatch.setenv(f"TRAJCACHE_{name.upper()}", value)
    with pytest.raises(ValidationError):
        Settings()
