"""The admin dashboard: one static page (HTML, JS, CSS; no build step) served at /dashboard.

The page reads the statistics API (`/v1/stats`, `/v1/plan-events`, `/v1/seed-jobs`,
`/v1/trajectories/{id}`) and draws its charts itself as SVG. Robots and seed jobs have tables of
their own: the stats groups say which a robot id is (`requester`). It holds no data: when API
keys are checked it asks for an admin key and sends it as `Authorization: Bearer <key>`.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

STATIC_DIR = Path(__file__).parent / "static"


def mount_dashboard(app: FastAPI) -> None:
    """Serve the dashboard at /dashboard/ (/dashboard redirects there)."""
    app.mount("/dashboard", StaticFiles(directory=STATIC_DIR, html=True), name="dashboard")
