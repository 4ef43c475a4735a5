"""`trajcache robots fetch`: a real robot's files, ready to register, in one command.

For each robot of the `example-robot-data` package that trajcache supports
(`trajcache.reference.example_robots`) it writes `<name>.urdf`, `<name>.srdf` (where the robot
has one) and `<name>-meshes.zip`, whose entries sit at the paths the URDF's `package://` URIs
resolve to, then prints the curl and Python client lines that register them. Both send the key
in TRAJCACHE_API_KEY (a seeder or admin key), so they work once the service checks keys; with
the variable unset or empty they send none, which a service without checks accepts.
"""

from __future__ import annotations

import shlex
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.markup import escape

from trajcache.cli.common import err_console, fail
from trajcache.cli.help import TidyCommand, TidyGroup

if TYPE_CHECKING:
    from trajcache.reference.example_robots import ExampleRobot


class RobotName(str, Enum):
    """The robots `robots fetch` writes (those of `example_robots.ROBOTS`, named here so that
    the command line's help loads no geometry)."""

    KINOVA = "kinova"
    PANDA = "panda"
    TIAGO = "tiago"
    UR5 = "ur5"
    XARM7 = "xarm7"
    Z1 = "z1"


app = typer.Typer(
    cls=TidyGroup, help="Real robot descriptions, ready to register.", no_args_is_help=True
)


def write_robot(robot: ExampleRobot, out: Path) -> dict[str, Path]:
    """Write the robot's URDF, SRDF (if any) and mesh archive into `out`; the paths by form
    field (`urdf`, `srdf`, `archive`)."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {"urdf": out / f"{robot.name}.urdf"}
    paths["urdf"].write_text(robot.urdf, encoding="utf-8")
    srdf = robot.srdf
    if srdf is not None:
        paths["srdf"] = out / f"{robot.name}.srdf"
        paths["srdf"].write_text(srdf, encoding="utf-8")
    paths["archive"] = out / f"{robot.name}-meshes.zip"
    paths["archive"].write_bytes(robot.archive())
    return paths


def _fields(robot: ExampleRobot) -> dict[str, str]:
    """The registration's text fields, beside its files."""
    fields = {"name": robot.name}
    if robot.group is not None:
        fields["group"] = robot.group
    if robot.joint_names is not None:
        fields["joint_names"] = ",".join(robot.joint_names)
    if robot.base != "fixed":
        fields["base"] = robot.base
    return fields


# The service's key header (`api.auth`), its value left to the shell: double quotes, expanded.
KEY_HEADER = '-H "X-API-Key: ${TRAJCACHE_API_KEY:-}"'


def curl_line(robot: ExampleRobot, paths: dict[str, Path], url: str) -> str:
    """The curl command that registers the written files (multipart), with the key in
    TRAJCACHE_API_KEY."""
    parts = [f"{key}=@{path}" for key, path in paths.items()]
    parts += [f"{key}={value}" for key, value in _fields(robot).items()]
    form = " ".join(f"-F {shlex.quote(part)}" for part in parts)
    return f"curl -s {KEY_HEADER} {shlex.quote(url + '/v1/robot-models')} {form}"


def client_line(robot: ExampleRobot, paths: dict[str, Path]) -> str:
    """The Python client call that registers the written files (`client` a `Client`, `Path`
    imported)."""
    args = [f"Path({str(paths['urdf'])!r}).read_text()"]
    if "srdf" in paths:
        args.append(f"srdf=Path({str(paths['srdf'])!r}).read_text()")
    for key, value in _fields(robot).items():
        if key == "joint_names":
            args.append(f"joint_names={list(robot.joint_names or ())!r}")
        else:
            args.append(f"{key}={value!r}")
    args.append(f"archive=Path({str(paths['archive'])!r})")
    return f"client.register_model({', '.join(args)})"


@app.command("fetch", cls=TidyCommand)
def fetch(
    names: Annotated[
        list[RobotName] | None,
        typer.Argument(
            metavar="ROBOT",
            help=f"Robots to write, of {', '.join(r.value for r in RobotName)} (default: all).",
        ),
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", metavar="DIR", help="Folder to write the files into.")
    ] = Path("robots"),
    url: Annotated[
        str, typer.Option(metavar="URL", help="The service the printed lines register with.")
    ] = "http://127.0.0.1:8000",
) -> None:
    """Write example-robot-data robots' URDF, SRDF and mesh archive; print how to register them.

    The robots come from the `example-robot-data` package: the `robots` extra of trajcache."""
    from trajcache.reference.example_robots import ROBOTS, robots_dir

    try:
        robots_dir()
    except LookupError as exc:
        raise fail(exc) from None
    console = Console(soft_wrap=True, highlight=False)
    url = url.rstrip("/")
    console.print(f"# Python: import os; from pathlib import Path; from trajcache_client import "
                  f"Client; client = Client({url!r}, "
                  'api_key=os.environ.get("TRAJCACHE_API_KEY") or None)')  # fmt: skip
    console.print("# With API keys on: export TRAJCACHE_API_KEY=<a seeder or admin key>")
    for name in names or list(RobotName):
        robot = ROBOTS[name.value]
        paths = write_robot(robot, out)
        shown = ", ".join(str(p) for p in paths.values())
        err_console().print(f"{robot.name}: wrote {escape(shown)}", soft_wrap=True)
        console.print(f"# {robot.name}")
        console.print(escape(curl_line(robot, paths, url)))
        console.print(escape(client_line(robot, paths)))
