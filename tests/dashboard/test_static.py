"""The dashboard's files are served by the app, self-contained (no CDN, no build output); the
vendored three.js is the npm package's files, unchanged."""

from __future__ import annotations

import hashlib
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
    "view3d.js": "text/javascript",
}
MODULES = {
    "view3d_stage.js": "text/javascript",
    "vendor/three/three.module.js": "text/javascript",
    "vendor/three/three.core.js": "text/javascript",
    "vendor/three/addons/controls/OrbitControls.js": "text/javascript",
    "vendor/three/addons/loaders/STLLoader.js": "text/javascript",
}
VENDOR = STATIC_DIR / "vendor" / "three"
IMPORT_MAP = {"three": "./vendor/three/three.module.js", "three/addons/": "./vendor/three/addons/"}


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
    for name, media in {**ASSETS, **MODULES}.items():
        reply = client.get(f"/dashboard/{name}")
        assert reply.status_code == 200, name
        assert reply.headers["content-type"].startswith(media), (name, reply.headers)
    assert client.get("/dashboard/__init__.py").status_code == 404  # only the static files


def _own_files() -> list[Path]:
    return [p for p in STATIC_DIR.rglob("*") if p.is_file() and VENDOR not in p.parents]


def test_nothing_is_loaded_from_elsewhere() -> None:
    for path in _own_files():
        text = path.read_text(encoding="utf-8")
        urls = re.findall(r"https?://[^\s\"')]+", text)
        assert urls == [] or all(u.startswith("http://www.w3.org/") for u in urls), (path, urls)


def test_modules_import_only_files_served_next_to_them() -> None:
    """ES modules, no bundler: every import is a relative file here or a name of the page's
    import map, which maps to the vendored three.js."""
    page = (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    assert '"imports": ' + str(IMPORT_MAP).replace("'", '"') in page
    modules = [p for p in STATIC_DIR.rglob("*.js")]
    for path in modules:
        text = path.read_text(encoding="utf-8")
        for target in re.findall(
            r'^\s*(?:import|export)\b[^;]*?\bfrom\s+["\']([^"\']+)["\']', text, re.M
        ):
            if target == "three":
                resolved = STATIC_DIR / IMPORT_MAP["three"]
            elif target.startswith("three/addons/"):
                resolved = STATIC_DIR / IMPORT_MAP["three/addons/"] / target[len("three/addons/") :]
            else:
                assert target.startswith("./"), (path, target)
                resolved = path.parent / target
            assert resolved.resolve().is_file(), (path, target)
    for name in ("charts.js", "dashboard.js"):  # classic scripts stay classic
        assert "import " not in (STATIC_DIR / name).read_text(encoding="utf-8"), name


def test_vendored_three_js_is_the_package_s_files_unchanged() -> None:
    notes = (VENDOR / "README.md").read_text(encoding="utf-8")
    version = re.search(r"three\.js \*\*(\d+\.\d+\.\d+)\*\*", notes)
    assert version is not None
    rows = re.findall(r"^\| `([^`]+)` \| `[^`]+` \| `([0-9a-f]{64})` \|$", notes, re.M)
    listed = {name: digest for name, digest in rows}
    present = {
        str(p.relative_to(VENDOR))
        for p in VENDOR.rglob("*")
        if p.is_file() and p.name != "README.md"
    }
    assert set(listed) == present
    for name, digest in listed.items():
        assert hashlib.sha256((VENDOR / name).read_bytes()).hexdigest() == digest, name
    assert "MIT License" in (VENDOR / "LICENSE").read_text(encoding="utf-8")
    revision = re.search(r"REVISION = '(\d+)'", (VENDOR / "three.core.js").read_text("utf-8"))
    assert revision is not None and version[1].split(".")[1] == revision[1]
