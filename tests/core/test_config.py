"""Settings: environment variables, URL normalisation, validation."""

from __future__ import annotations

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
    assert settings.database_url == "sqlite:///./trajcache.db"
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
    ("name", "value"),
    [
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
