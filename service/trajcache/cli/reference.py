"""`trajcache reference robot|scene`: write the reference robot (URDF) and the restroom scene."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer
import yaml

from trajcache.cli.help import TidyCommand, TidyGroup

app = typer.Typer(
    cls=TidyGroup, help="Write the reference robot and restroom scene.", no_args_is_help=True
)

OutOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Write to this file instead of stdout.")
]


class SceneFormat(str, Enum):
    """Output formats of `trajcache reference scene`."""

    JSON = "json"
    YAML = "yaml"
    MOVEIT = "moveit"


def _angles(text: str, option: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise typer.BadParameter(
            f"expected comma-separated degrees, got {text!r}", param_hint=option
        ) from None


def _emit(text: str, out: Path | None) -> None:
    if out is None:
        typer.echo(text, nl=not text.endswith("\n"))
    else:
        out.write_text(text if text.endswith("\n") else text + "\n", encoding="utf-8")


@app.command("robot", cls=TidyCommand)
def robot(out: OutOption = None) -> None:
    """Write the reference robot's URDF."""
    from trajcache.reference.robot import reference_urdf

    _emit(reference_urdf(), out)


@app.command("scene", cls=TidyCommand)
def scene(
    doors: Annotated[
        str, typer.Option(metavar="DEGREES", help="Door angles in degrees: one, or one per stall.")
    ] = "0",
    seats: Annotated[
        str, typer.Option(metavar="DEGREES", help="Seat angles in degrees: one, or one per stall.")
    ] = "0",
    fmt: Annotated[SceneFormat, typer.Option("--format", help="Output format.")] = SceneFormat.JSON,
    seed: Annotated[int | None, typer.Option(help="Seed for --jitter.")] = None,
    jitter: Annotated[
        float, typer.Option(metavar="METRES", help="Shift fixtures by up to this many metres.")
    ] = 0.0,
    out: OutOption = None,
) -> None:
    """Write the restroom scene for the given door and seat angles."""
    from trajcache.geometry.errors import SceneError
    from trajcache.geometry.scene.moveit import scene_to_moveit
    from trajcache.geometry.scene.payload import scene_to_payload
    from trajcache.reference.restroom import restroom_scene

    try:
        built = restroom_scene(
            _angles(doors, "--doors"), _angles(seats, "--seats"), seed=seed, jitter_m=jitter
        )
    except SceneError as exc:
        raise typer.BadParameter(str(exc)) from None
    payload: dict[str, Any]
    if fmt is SceneFormat.MOVEIT:
        payload = scene_to_moveit(built, name="restroom")
    else:
        payload = scene_to_payload(built)
    if fmt is SceneFormat.YAML:
        text = yaml.safe_dump(payload, sort_keys=False, default_flow_style=None)
    else:
        text = json.dumps(payload, indent=1)
    _emit(text, out)
