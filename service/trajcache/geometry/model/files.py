"""Uploaded files: zip and tar archives unpacked safely, and the meshes a URDF refers to."""

from __future__ import annotations

import hashlib
import io
import re
import stat
import tarfile
import zipfile
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np
import trimesh

from trajcache.geometry.errors import GeometryError, MeshError, RobotModelError, UnsafePathError
from trajcache.geometry.model.shapes import FloatArray, Shape, ShapeKind

MiB = 1024 * 1024
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def unpack_archive(
    data: bytes, *, max_entries: int = 1000, max_total_bytes: int = 64 * MiB
) -> dict[str, bytes]:
    """Unpack a zip or (compressed) tar archive into {normalised relative path: content}."""
    buffer = io.BytesIO(data)
    try:
        if data[:4] in (b"PK\x03\x04", b"PK\x05\x06"):
            with zipfile.ZipFile(buffer) as archive:
                return _unpack_zip(archive, max_entries, max_total_bytes)
        with tarfile.open(fileobj=buffer, mode="r:*") as tar:
            return _unpack_tar(tar, max_entries, max_total_bytes)
    except GeometryError:
        raise
    except (tarfile.TarError, zipfile.BadZipFile, zlib.error, EOFError, OSError) as exc:
        raise RobotModelError(f"unreadable archive (expected zip or tar): {exc}") from exc
    except (RuntimeError, NotImplementedError) as exc:  # encrypted or unsupported compression
        raise RobotModelError(f"unsupported archive entry: {exc}") from exc


def _unpack_zip(archive: zipfile.ZipFile, max_entries: int, max_total: int) -> dict[str, bytes]:
    infos = archive.infolist()
    if len(infos) > max_entries:
        raise RobotModelError(f"archive has {len(infos)} entries, at most {max_entries} allowed")
    out: dict[str, bytes] = {}
    for info in infos:
        if stat.S_ISLNK(info.external_attr >> 16):
            raise UnsafePathError(f"archive entry {info.filename!r} is a symbolic link")
        path = normalise_path(info.filename, "archive entry")
        if info.is_dir():
            continue
        with archive.open(info) as fh:
            _store(out, path, fh.read(max_total - sum(map(len, out.values())) + 1), max_total)
    return out


def _unpack_tar(tar: tarfile.TarFile, max_entries: int, max_total: int) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    for count, member in enumerate(tar, start=1):
        if count > max_entries:
            raise RobotModelError(f"archive has more than {max_entries} entries")
        if member.issym() or member.islnk():
            raise UnsafePathError(f"archive entry {member.name!r} is a link")
        path = normalise_path(member.name, "archive entry")
        if member.isdir():
            continue
        if not member.isfile():
            raise UnsafePathError(f"archive entry {member.name!r} is not a regular file")
        if member.size + sum(map(len, out.values())) > max_total:
            raise RobotModelError(f"archive content exceeds {max_total} bytes")
        fh = tar.extractfile(member)
        _store(out, path, fh.read() if fh is not None else b"", max_total)
    return out


def _store(out: dict[str, bytes], path: str, content: bytes, max_total: int) -> None:
    if path in out:
        raise RobotModelError(f"archive contains {path!r} twice")
    out[path] = content
    if sum(map(len, out.values())) > max_total:
        raise RobotModelError(f"archive content exceeds {max_total} bytes")


def normalise_path(path: str, what: str) -> str:
    """Normalise a relative path ('/'-separated, no '.'/'..'); raise UnsafePathError on escapes."""
    path = path.replace("\\", "/")
    if path.startswith("/") or SCHEME.match(path):
        raise UnsafePathError(f"{what} {path!r} is an absolute path or URL")
    parts: list[str] = []
    for part in path.split("/"):
        if part == "..":
            if not parts:
                raise UnsafePathError(f"{what} {path!r} escapes the uploaded files")
            parts.pop()
        elif part not in ("", "."):
            parts.append(part)
    if not parts:
        raise UnsafePathError(f"{what} {path!r} is empty")
    return "/".join(parts)


class MeshResolver:
    """Finds mesh URIs in the uploaded files and loads them once each."""

    def __init__(self, files: Mapping[str, bytes]) -> None:
        self.files = {normalise_path(k, "file"): v for k, v in files.items()}
        self.used: dict[str, str] = {}  # path → sha256 of the files actually referenced
        self._meshes: dict[str, tuple[FloatArray, np.ndarray]] = {}

    def resolve(self, uri: str) -> str:
        """Path in `files` of a `package://` or relative mesh URI."""
        uri = uri.strip()
        if uri.lower().startswith("package://"):
            package, _, sub = uri[len("package://") :].partition("/")
            sub = normalise_path(sub, f"mesh URI {uri!r}: path")
            candidates = [sub, f"{package}/{sub}"]
        elif SCHEME.match(uri) or uri.replace("\\", "/").startswith("/"):
            raise UnsafePathError(
                f"mesh URI {uri!r} is absolute or uses a scheme other than package://; "
                "only files inside the upload can be referenced"
            )
        else:
            candidates = [normalise_path(uri, "mesh URI")]
        for path in candidates:
            if path in self.files:
                return path
        raise MeshError(f"mesh {uri!r} not found in the uploaded files (tried {candidates})")

    def shape(self, uri: str, scale: Any) -> Shape:
        """Mesh shape of `uri`, scaled."""
        path = self.resolve(uri)
        if path not in self._meshes:
            data = self.files[path]
            self.used[path] = hashlib.sha256(data).hexdigest()
            kind = path.rsplit(".", 1)[-1].lower() if "." in path else ""
            try:
                mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh")
            except Exception as exc:
                raise MeshError(f"mesh {uri!r} is unreadable: {exc}") from exc
            if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
                raise MeshError(f"mesh {uri!r} has no triangles")
            vertices = np.asarray(mesh.vertices, dtype=float)
            self._meshes[path] = (vertices, np.asarray(mesh.faces, dtype=np.int64))
        vertices, faces = self._meshes[path]
        factor = np.ones(3) if scale is None else np.broadcast_to(np.asarray(scale, float), 3)
        return Shape(kind=ShapeKind.MESH, vertices=vertices * factor, faces=faces)
