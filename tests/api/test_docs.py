"""/docs and /redoc load everything from the service itself: they work without the internet.

The browser test opens both pages in headless Chromium with every request that leaves the
service refused, and checks that they draw the document. It needs Debian's chromium
(`/usr/bin/chromium`, driven by Playwright): skipped without it, failed when
TRAJCACHE_REQUIRE_SERVICES=1.
"""

from __future__ import annotations

import re
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
import uvicorn
from fastapi.testclient import TestClient

from tests.conftest import REQUIRE_SERVICES
from tests.waiting import wait_until
from trajcache.api.docs import STATIC_DIR
from trajcache.core.config import Settings
from trajcache.main import create_app

CHROMIUM = Path("/usr/bin/chromium")
WAIT_MS = 60_000  # generous: the machine running the tests may be busy
# Where a page names another resource: attributes, and the document's address in Swagger UI.
_REFERENCE = re.compile(r"""(?:href|src|spec-url)="([^"]*)"|\burl: '([^']*)'""")


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'docs.db'}", worker_prestart=False)
    with TestClient(create_app(settings)) as client:
        yield client


def _references(html: str) -> list[str]:
    return [href or url for href, url in _REFERENCE.findall(html)]


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_the_docs_reference_only_the_service(client: TestClient, page: str) -> None:
    reply = client.get(page)
    assert reply.status_code == 200 and reply.headers["content-type"].startswith("text/html")
    assert not re.findall(r"https?://|//[a-z]", reply.text, re.IGNORECASE), reply.text
    assert reply.headers["content-security-policy"].startswith("default-src 'self';")
    references = _references(reply.text)
    assert "/openapi.json" in references and len(references) >= 3, references
    for reference in references:
        assert reference.startswith("/") and not urlsplit(reference).netloc, reference
        asset = client.get(reference)
        assert asset.status_code == 200 and asset.content, reference


def test_the_viewers_are_the_vendored_files_their_notice_names(client: TestClient) -> None:
    bundle = client.get("/docs/assets/swagger-ui/swagger-ui-bundle.js")
    assert bundle.content == (STATIC_DIR / "swagger-ui/swagger-ui-bundle.js").read_bytes()
    css = client.get("/docs/assets/swagger-ui/swagger-ui.css")
    assert css.headers["content-type"].startswith("text/css")
    redoc = (STATIC_DIR / "redoc/redoc.standalone.js").read_text(encoding="utf-8")
    built = {
        "swagger-ui-dist": re.search(r'PACKAGE_VERSION:"([0-9.]+)"', bundle.text),
        "redoc": re.search(r'ReDoc Version: ","([0-9.]+)"', redoc),
    }
    notice = (STATIC_DIR / "NOTICE.md").read_text(encoding="utf-8")
    for package, found in built.items():
        assert found, package
        assert f"`{package}`](https://www.npmjs.com/package/{package}) | {found[1]} |" in notice
    assert (STATIC_DIR / "swagger-ui/LICENSE").is_file() and (
        STATIC_DIR / "redoc/LICENSE"
    ).is_file()


def _require_browser() -> Any:
    """Playwright's sync API, or a skip (a failure in CI) when the browser is missing."""
    problem = None
    if not CHROMIUM.exists():
        problem = f"{CHROMIUM} is not installed (apt-get install chromium)"
    try:
        from playwright import sync_api
    except ImportError:
        problem = problem or "the playwright package is not installed"
    if problem:
        if REQUIRE_SERVICES:
            pytest.fail(f"{problem} and TRAJCACHE_REQUIRE_SERVICES=1")
        pytest.skip(problem)
    return sync_api


@pytest.fixture
def served(tmp_path: Path) -> Iterator[str]:
    """The app in uvicorn on loopback; its base URL."""
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'docs.db'}", worker_prestart=False)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    config = uvicorn.Config(create_app(settings), log_level="warning", lifespan="on")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started or not thread.is_alive(), timeout_s=60)
    assert server.started, "the server did not start"
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}"
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()


@pytest.mark.slow
def test_the_docs_draw_the_document_with_the_internet_cut_off(served: str) -> None:
    sync_api = _require_browser()
    refused: list[str] = []
    errors: list[str] = []

    def only_the_service(route: Any) -> None:
        if route.request.url.startswith(served):
            route.continue_()
        else:
            refused.append(route.request.url)
            route.abort()

    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"]
        )
        try:
            tab = browser.new_page()
            tab.route("**/*", only_the_service)
            tab.on("pageerror", lambda exc: errors.append(f"uncaught: {exc}"))
            tab.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            tab.goto(f"{served}/docs")
            plan = "#operations-plan-plan_route_v1_robots__robot_id__plan_post"
            tab.wait_for_selector(plan, timeout=WAIT_MS)
            assert tab.locator(".opblock").count() > 20
            tab.goto(f"{served}/redoc")
            tab.wait_for_selector("h2:has-text('Plan from start to goal')", timeout=WAIT_MS)
        finally:
            browser.close()
    # The page's policy refuses ReDoc's logo before any request is made; nothing else is refused.
    logo = "Loading the image 'https://cdn.redoc.ly/redoc/logo-mini.svg' violates"
    assert refused == [] and [e for e in errors if not e.startswith(logo)] == [], errors
