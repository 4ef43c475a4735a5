"""`trajcache robots fetch`: a supported robot's files, laid out as an upload resolves them,
with the lines that register them; without `example-robot-data`, what to install."""

from __future__ import annotations

import sysconfig
import zipfile
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trajcache.cli import app
from trajcache.cli.robots import RobotName
from trajcache.geometry.model.files import MeshResolver, unpack_archive
from trajcache.reference.example_robots import _MESH_URI, ROBOTS


def test_the_command_offers_every_supported_robot() -> None:
    assert sorted(r.value for r in RobotName) == sorted(ROBOTS)


def test_fetch_writes_the_files_and_prints_how_to_register_them(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["robots", "fetch", "panda", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "panda-meshes.zip",
        "panda.srdf",
        "panda.urdf",
    ]
    panda = ROBOTS["panda"]
    assert (tmp_path / "panda.urdf").read_text() == panda.urdf
    assert (tmp_path / "panda.srdf").read_text() == panda.srdf
    archive = (tmp_path / "panda-meshes.zip").read_bytes()
    with zipfile.ZipFile(tmp_path / "panda-meshes.zip") as written:
        assert all(name.startswith("robots/panda_description/") for name in written.namelist())
    resolver = MeshResolver(unpack_archive(archive))
    uris = {f"package://example-robot-data/robots/{p}" for p in _MESH_URI.findall(panda.urdf)}
    assert len(uris) > 10
    for uri in uris:  # every mesh the URDF names is in the archive, where the service looks
        resolver.resolve(uri)
    lines = result.stdout.splitlines()
    curl = f"curl -s http://127.0.0.1:8000/v1/robot-models -F urdf=@{tmp_path}/panda.urdf"
    assert any(line.startswith(curl) for line in lines), lines
    assert any(line.startswith("client.register_model(") for line in lines), lines


def test_without_example_robot_data_it_says_what_to_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    empty = {key: str(tmp_path / key) for key in ("purelib", "platlib", "data")}
    monkeypatch.setattr(sysconfig, "get_paths", lambda: empty)
    result = CliRunner().invoke(app, ["robots", "fetch", "ur5", "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "pip install 'trajcache[robots]'" in result.output
    assert not (tmp_path / "out").exists()
