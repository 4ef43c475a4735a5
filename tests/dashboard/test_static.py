"""The dashboard's files are served by the app, self-contained (no CDN, no build output)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from trajcache.core.config import Settings
from trajcache.dashboard import STATIC_DIR
from trajcache.main import create_app

ASSETS = {
    "index.html": "text/html",
    "charts.js": "text/javascript",
    "dashboard.js": "text/javascript",
    "dashboard.css": "text/css",
}


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'd.db'}", worker_prestart=False)
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def test_the_page_and_its_assets_are_served(client: TestClient) -> None:
    moved = client.get("/dashboard", follow_redirects=False)
    assert moved.status_code in (301, 307) and moved.headers["location"].endswith("/dashboard/")
    page = client.get("/dashboard/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    referenced = set(re.findall(r'(?:src|href)="([^":]+)"', page.text))
    assert referenced == set(ASSETS) - {"index.html"}
    for name, media in ASSETS.items():
        reply = client.get(f"/dashboard/{name}")
        assert reply.status_code == 200, name
        assert reply.headers["content-type"].startswith(media), (name, reply.headers)
    assert client.get("/dashboard/__init__.py").status_code == 404  # only the static files


def test_nothing_is_loaded_from_elsewhere() -> None:
    for path in STATIC_DIR.iterdir():
        text = path.read_text(encoding="utf-8")
        urls = re.findall(r"https?://[^\s\"')]+", text)
        assert urls == [] or all(u.startswith("http://www.w3.org/") for u in urls), (path, urls)
        assert "import " not in text or path.suffix != ".js", path  # no modules to bundle
