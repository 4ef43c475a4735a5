"""`python -m trajcache.cli`: the `trajcache` command line."""

from __future__ import annotations

from trajcache.cli.app import app

app()
