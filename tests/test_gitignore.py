"""A SQLite database in the checkout leaves nothing for git to show: the file, its write-ahead
log, its shared memory and its journal are all ignored."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SIDE_FILES = [
    "trajcache.db",
    "trajcache.db-wal",
    "trajcache.db-shm",
    "trajcache.db-journal",
    "cache.sqlite-wal",
    "cache.sqlite-shm",
]


def test_sqlite_files_and_their_side_files_are_ignored() -> None:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    done = subprocess.run(
        ["git", "check-ignore", "--no-index", *SIDE_FILES],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert done.stdout.split() == SIDE_FILES
