"""`trajcache seed FILE`: submit a seed job to the running service and follow it.

The job runs in the service (where the shared cache and the worker pool are), so the command
talks to it over HTTP: `--url` (or TRAJCACHE_URL, default http://127.0.0.1:8000) and, when the
service checks keys, `--api-key` (or TRAJCACHE_API_KEY; a `seeder` or `admin` key). FILE is the
job in JSON or YAML, in the format of `POST /v1/seed-jobs` (documented in
`trajcache.services.seeding.spec`), except that it may name its model instead of giving its
`model_id`: `model: reference` is the reference robot (registered by the command if the service
lacks it, as `trajcache reference robot` writes it, with a planar base), any other name that of a
model registered in the service. `--model` fills in or replaces the `model_id`.

A Rich progress bar follows the job until it ends. Ctrl-C stops following (the job keeps
running in the service) unless `--cancel-on-interrupt` is given. Exit status: 0 when the job
completed, 1 when it failed or was cancelled, 2 when the service refused the job.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
import yaml
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from trajcache_client import NO_RETRY, APIError, Client, SeedJob, TransportError

DEFAULT_URL = "http://127.0.0.1:8000"
ACTIVE = ("queued", "running")
REFERENCE = "reference"  # `model: reference`: the reference robot

UrlOption = Annotated[
    str,
    typer.Option(
        "--url", metavar="URL", envvar="TRAJCACHE_URL", help="Base URL of the trajcache service."
    ),
]
KeyOption = Annotated[
    str | None,
    typer.Option(
        "--api-key", metavar="KEY", envvar="TRAJCACHE_API_KEY", help="API key (seeder or admin)."
    ),
]


class ServiceError(Exception):
    """The service answered with an error, or could not be reached."""

    def __init__(self, message: str, exit_code: int = 1) -> None:
        super().__init__(message)
        self.exit_code = exit_code


def read_job_file(path: Path) -> dict[str, Any]:
    """The job document of FILE (JSON or YAML)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise typer.BadParameter(f"cannot read {path}: {exc.strerror}", param_hint="FILE") from None
    try:
        data = json.loads(text)
    except ValueError:
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise typer.BadParameter(
                f"{path} is neither JSON nor YAML: {exc}", param_hint="FILE"
            ) from None
    if not isinstance(data, dict):
        raise typer.BadParameter(f"{path} must hold one object (the job)", param_hint="FILE")
    return data


def make_client(url: str, api_key: str | None) -> Client:
    """A client of the service (errors are reported, not retried)."""
    return Client(url, api_key=api_key or None, timeout=60.0, retry=NO_RETRY)


def _call(client: Client, call: Callable[[], SeedJob]) -> SeedJob:
    try:
        return call()
    except TransportError as exc:
        raise ServiceError(
            f"cannot reach the service at {client.base_url} ({exc}); start it with "
            "`trajcache serve`, or point --url / TRAJCACHE_URL at it"
        ) from None
    except APIError as exc:
        request, status = exc.response.request, exc.status_code
        code = 2 if status in (404, 409, 413, 422) else 1
        raise ServiceError(f"{request.method} {request.url.path}: {refusal(exc)}", code) from None


def refusal(exc: APIError) -> str:
    """The service's status and reason; a 401 or 403 says how to give the command a key."""
    text = f"{exc.status_code} {exc.detail}"
    if exc.status_code == 401:
        text += "; give the command a seeder or admin key with --api-key or TRAJCACHE_API_KEY"
    elif exc.status_code == 403:
        text += "; --api-key / TRAJCACHE_API_KEY must be a seeder or admin key"
    return text


def _named_model(client: Client, name: str) -> str:
    """The id of the one model of the service named `name` (the reference robot registered)."""
    if name == REFERENCE:
        from trajcache.reference.robot import REFERENCE_BASE, reference_urdf

        return client.register_model(reference_urdf(), base=REFERENCE_BASE).model_id
    ids, offset = [], 0
    while True:
        page = client.list_models(offset=offset)
        ids += [m.model_id for m in page.items if m.name == name]
        offset += len(page.items)
        if not page.items or offset >= page.total:
            break
    if len(ids) != 1:
        found = "no model" if not ids else f"{len(ids)} models ({', '.join(ids)})"
        raise ServiceError(
            f"model: {found} named {name!r} in the service; give its model_id, "
            f"or `model: {REFERENCE}` for the reference robot",
            exit_code=2,
        )
    return ids[0]


def resolve_model(client: Client, body: dict[str, Any]) -> dict[str, Any]:
    """The job with `model: NAME` replaced by the model's `model_id`."""
    if "model" not in body:
        return body
    name = body.pop("model")
    if "model_id" in body:
        raise ServiceError("give the job's model_id or its model (a name), not both", 2)
    if not isinstance(name, str) or not name.strip():
        raise ServiceError(f"model must be a model's name, got {name!r}", 2)
    try:
        return {"model_id": _named_model(client, name.strip()), **body}
    except APIError as exc:
        raise ServiceError(f"model {name!r}: {refusal(exc)}", 2) from None


def _progress(console: Console) -> Progress:
    return Progress(
        SpinnerColumn(),
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn(
            "hits {task.fields[hits]} · planned {task.fields[planned]} · "
            "failed {task.fields[failed]}"
        ),
        TimeElapsedColumn(),
        TextColumn("{task.fields[eta]}"),
        console=console,
    )


def follow(client: Client, job: SeedJob, console: Console, poll_s: float) -> SeedJob:
    """Show the job's progress until it ends; its last state."""
    job_id = job.job_id
    with _progress(console) as bar:
        task = bar.add_task(
            f"seed job {job_id}", total=job.total, hits=0, planned=0, failed=0, eta=""
        )
        while True:
            eta = job.eta_s
            bar.update(
                task,
                completed=job.done,
                hits=job.hits,
                planned=job.planned,
                failed=job.failed,
                eta="" if eta is None else f"ETA {eta:.0f} s",
            )
            if job.state not in ACTIVE:
                return job
            time.sleep(poll_s)
            job = _call(client, lambda: client.get_seed_job(job_id))


def summary(job: SeedJob) -> Table:
    """The job's outcome as a table."""
    table = Table(title=f"seed job {job.job_id}: {job.state}", show_header=False)
    rate = job.hit_rate
    table.add_row("requests", f"{job.done} of {job.total}")
    table.add_row("cache hits", f"{job.hits}" + ("" if rate is None else f" ({rate:.1%})"))
    if job.stored is None:  # a job begun before stored paths were counted apart
        table.add_row("planned", str(job.planned))
    else:
        table.add_row("planned and stored (as sim)", str(job.stored))
        table.add_row("planned, already stored", str(job.planned - job.stored))
    table.add_row("failed", str(job.failed))
    if job.message:
        table.add_row("message", str(job.message))
    for error in job.errors[-5:]:
        table.add_row(f"failed #{error.index}", f"{error.label}: {error.reason}")
    return table


def seed(
    file: Annotated[Path, typer.Argument(help="The job, JSON or YAML (POST /v1/seed-jobs body).")],
    url: UrlOption = DEFAULT_URL,
    api_key: KeyOption = None,
    model: Annotated[
        str | None,
        typer.Option(
            "--model", metavar="MODEL_ID", help="Model id (fills in or replaces model_id)."
        ),
    ] = None,
    wait: Annotated[bool, typer.Option(help="Follow the job until it ends.")] = True,
    poll_s: Annotated[
        float, typer.Option(min=0.05, metavar="SECONDS", help="Seconds between progress reads.")
    ] = 0.5,
    cancel_on_interrupt: Annotated[
        bool, typer.Option(help="Cancel the job on Ctrl-C (default: stop following only).")
    ] = False,
) -> None:
    """Submit a seed job to the running service and show its progress until it ends."""
    body = read_job_file(file)
    if model is not None:
        body.pop("model", None)
        body["model_id"] = model
    console = Console(stderr=True)
    with make_client(url, api_key) as client:
        try:
            job = _call(client, lambda: client.create_seed_job(resolve_model(client, body)))
            console.print(f"queued seed job [bold]{job.job_id}[/bold]: {job.total} requests")
            if not wait:
                typer.echo(job.job_id)
                return
            try:
                job = follow(client, job, console, poll_s)
            except KeyboardInterrupt:
                if cancel_on_interrupt:
                    job_id = job.job_id
                    job = _call(client, lambda: client.cancel_seed_job(job_id))
                    console.print(f"cancelled seed job {job.job_id}")
                else:
                    console.print(
                        f"stopped following; seed job {job.job_id} keeps running "
                        f"(cancel: DELETE /v1/seed-jobs/{job.job_id})"
                    )
                raise typer.Exit(130) from None
        except ServiceError as exc:
            console.print(f"[red]error:[/red] {exc}")
            raise typer.Exit(exc.exit_code) from None
    Console().print(summary(job))
    if job.state != "completed":
        raise typer.Exit(1)
