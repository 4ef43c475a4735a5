"""PostgreSQL goes away under plan and write load, and comes back; the app is not restarted.

Two outages, the same checks: connections cut by a proxy that then refuses new ones for a few
seconds (always run), and a real stop and start of the server (run when
TRAJCACHE_FAULT_RESTART_POSTGRES=1, as CI does: it disturbs everyone using the server).
"""

from __future__ import annotations

import os
import subprocess
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
import sqlalchemy as sa

from tests.client.conftest import LiveServer
from tests.conftest import POSTGRES_URL, require_service
from tests.faults.load import ROBOT, Load, Outcome, check_database, seed_trajectories
from tests.proxy import TcpProxy
from tests.robots import TWO_JOINT_URDF
from trajcache.core.config import Settings
from trajcache.jobs.local import LocalBackend
from trajcache.jobs.pool import OVERHEAD_S
from trajcache.main import create_app
from trajcache.services.context import ServiceContext

pytestmark = [pytest.mark.postgres, pytest.mark.serial]

RESTART_ENV = "TRAJCACHE_FAULT_RESTART_POSTGRES"
BUDGET_S = 2.0  # planning budget of the misses
HEALTHY_S = 1.0  # load before the outage
OUTAGE_S = 2.5
MAX_ANSWER_S = BUDGET_S + OVERHEAD_S + 2.0  # no request may take longer, outage or not
RECOVERED_AFTER_S = 1.0  # every request sent this long after the database is back succeeds


def run_through_outage(
    app_database_url: str, database_url: str, down: Callable[[], None], up: Callable[[], None]
) -> None:
    """Drive load at the app on `app_database_url`, call `down`, wait, call `up`; check all."""
    settings = Settings(database_url=app_database_url, worker_processes=1, plan_budget_s=BUDGET_S)
    app = create_app(settings)
    with LiveServer(app) as server, httpx.Client(base_url=server.url, timeout=30.0) as client:
        ctx: ServiceContext = app.state.ctx
        model_id = client.post("/v1/robot-models", json={"urdf": TWO_JOINT_URDF}).json()["model_id"]
        assert client.put(f"/v1/robots/{ROBOT}", json={"model_id": model_id}).status_code == 201
        assert client.put(f"/v1/robots/{ROBOT}/scene", json={"objects": []}).status_code == 200
        load = Load(server.url, model_id, seed_trajectories(client, model_id, count=4))
        pool = ctx.planner_pool()
        assert pool is not None and isinstance(pool.backend, LocalBackend)
        assert pool.backend.wait_ready(30.0)

        load.start()
        try:
            time.sleep(HEALTHY_S)
            going_down = time.monotonic()
            down()
            went_down = time.monotonic()
            time.sleep(OUTAGE_S)
            restoring = time.monotonic()
            up()
            came_up = time.monotonic()
            recovered = load.wait_for_successes(since=came_up, count=3, timeout=30.0)
        finally:
            load.stop()
        assert recovered, "the app did not recover: " + _summary(load.of()[-10:])
        assert app.state.ctx is ctx  # the same app, never restarted

        check_answers(load, (going_down, went_down), (restoring, came_up))
        engine = sa.create_engine(database_url)
        try:
            check_database(engine, load, ctx)
        finally:
            engine.dispose()


def check_answers(load: Load, down: tuple[float, float], up: tuple[float, float]) -> None:
    """Successes, or 503s with a clear message; never a 500, never a hang. `down` and `up` are
    when taking the database down and bringing it back began and ended: all is well before,
    all 503s between, and all is well again once it is back."""
    (going_down, went_down), (restoring, came_up) = down, up
    outcomes = load.of()
    wrong = [o for o in outcomes if not (o.ok or _clear_503(o))]
    assert not wrong, _summary(wrong)
    slow = [o for o in outcomes if o.took > MAX_ANSWER_S]
    assert not slow, _summary(slow)
    healthy = [o for o in outcomes if o.ended < going_down]
    assert healthy and all(o.ok for o in healthy), _summary([o for o in healthy if not o.ok])
    during = [o for o in outcomes if o.began > went_down and o.ended < restoring]
    assert {o.kind for o in during} == set(load.threads), "the outage was not exercised"
    assert all(o.status == 503 for o in during), _summary([o for o in during if o.ok])
    after = [o for o in outcomes if o.began > came_up + RECOVERED_AFTER_S]
    assert all(o.ok for o in after), _summary([o for o in after if not o.ok])


def _clear_503(outcome: Outcome) -> bool:
    detail = outcome.body.get("detail") if isinstance(outcome.body, dict) else None
    return outcome.status == 503 and isinstance(detail, str) and "unavailable" in detail


def _summary(outcomes: list[Outcome]) -> str:
    return "\n".join(o.describe() for o in outcomes[:20])


def test_database_connections_cut_under_load(postgres_url: str) -> None:
    proxy = TcpProxy(("127.0.0.1", 5432))
    proxy.start()
    proxied = postgres_url.replace("127.0.0.1:5432", f"127.0.0.1:{proxy.port}")
    assert proxied != postgres_url
    try:
        run_through_outage(proxied, postgres_url, down=proxy.stop, up=proxy.start)
    finally:
        proxy.stop()


# --- a real restart of the server ---


def _cluster() -> list[str]:
    versions = sorted(p.name for p in Path("/etc/postgresql").glob("*"))
    if not versions:
        pytest.skip("no local PostgreSQL cluster to restart")
    return ["pg_ctlcluster", "--skip-systemctl-redirect", versions[-1], "main"]


def _pg(action: str, *options: str) -> None:
    subprocess.run([*_cluster(), action, *options], check=True, timeout=60, capture_output=True)


def _admin(url: str, sql: str) -> None:
    """Run `sql` on a connection of its own (pooled ones do not survive a restart)."""
    engine = sa.create_engine(url, poolclass=sa.pool.NullPool, isolation_level="AUTOCOMMIT")
    try:
        with engine.connect() as conn:
            conn.execute(sa.text(sql))
    finally:
        engine.dispose()


@pytest.fixture
def restartable_postgres() -> Iterator[str]:
    """An empty schema on a server this test may stop; the server runs again afterwards."""
    if os.environ.get(RESTART_ENV) != "1":
        pytest.skip(f"stops the shared PostgreSQL server; set {RESTART_ENV}=1 to run")
    require_service("PostgreSQL", "127.0.0.1", 5432)
    schema = f"t_{uuid.uuid4().hex[:12]}"
    _admin(POSTGRES_URL, f'CREATE SCHEMA "{schema}"')
    try:
        yield f"{POSTGRES_URL}?options=-csearch_path%3D{schema}"
    finally:
        deadline = time.monotonic() + 60.0
        while True:
            try:
                _admin(POSTGRES_URL, f'DROP SCHEMA "{schema}" CASCADE')
                break
            except sa.exc.OperationalError:  # still down: start it (again)
                assert time.monotonic() < deadline, "PostgreSQL did not come back"
                subprocess.run([*_cluster(), "start"], timeout=60, capture_output=True)
                time.sleep(0.5)


def test_database_restarted_under_load(restartable_postgres: str) -> None:
    run_through_outage(
        restartable_postgres,
        restartable_postgres,
        down=lambda: _pg("stop", "-m", "fast"),
        up=lambda: _pg("start"),
    )
