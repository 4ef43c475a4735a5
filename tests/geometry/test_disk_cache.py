"""Content-keyed arrays on disk: reused, keyed by all they depend on, rebuilt when unreadable."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trajcache.geometry.disk_cache import cached_arrays, digest


def test_an_entry_is_built_once_and_read_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TRAJCACHE_PLANNER_CACHE_DIR", str(tmp_path))
    builds: list[int] = []

    def build() -> dict[str, np.ndarray]:
        builds.append(1)
        return {"x": np.arange(3.0)}

    key = digest([np.arange(4), "mesh", 0.008])
    first = cached_arrays("kind", key, build)
    again = cached_arrays("kind", key, build)
    assert len(builds) == 1
    np.testing.assert_array_equal(first["x"], again["x"])
    (tmp_path / "kind" / f"{key}.npz").write_bytes(b"not a zip")  # unreadable: built again
    np.testing.assert_array_equal(cached_arrays("kind", key, build)["x"], np.arange(3.0))
    assert len(builds) == 2


def test_the_key_depends_on_every_part() -> None:
    base = [np.arange(4.0), "mesh", 0.008]
    keys = {
        digest(base),
        digest([np.arange(4.0) + 1e-12, "mesh", 0.008]),
        digest([np.arange(4.0).astype(np.float32), "mesh", 0.008]),
        digest([np.arange(4.0).reshape(2, 2), "mesh", 0.008]),
        digest([np.arange(4.0), "box", 0.008]),
        digest([np.arange(4.0), "mesh", 0.004]),
    }
    assert len(keys) == 6
    assert digest(base) == digest([np.arange(4.0), "mesh", 0.008])


def test_off_keeps_nothing_on_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRAJCACHE_PLANNER_CACHE_DIR", "off")
    monkeypatch.chdir(tmp_path)
    assert cached_arrays("kind", "k", lambda: {"x": np.ones(2)})["x"].sum() == 2.0
    assert not any(tmp_path.iterdir())
