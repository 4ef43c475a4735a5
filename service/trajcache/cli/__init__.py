"""The `trajcache` command line (`app`); `python -m trajcache.cli` runs it too."""

from __future__ import annotations

from trajcache.cli.app import app

__all__ = ["app"]
