"""A robot model as the 3D view draws it: its links and each link's collision geometry.

Each collision element is given on its link with its pose in the link frame: a primitive by its
kind and size (cylinders and capsules along their local z, sizes as `Shape` gives them), a mesh
by the index of its STL file (`element_stl`). The STL holds the triangles the validator checks
(a mesh is loaded once at registration, scaled, and centred on its box with the element's
origin moved the other way), so what is drawn is what was checked, whatever format the
uploaded file had. The files as uploaded are served too (`services.view.files`).
"""

from __future__ import annotations

from dataclasses import dataclass

import trimesh
from sqlalchemy.orm import Session

from trajcache.geometry.model.poses import pose7
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.shapes import ShapeKind
from trajcache.geometry.path_quality import end_effector_link
from trajcache.services.catalog.models import ModelRegistry, get_model
from trajcache.services.errors import NotFoundError

__all__ = ["ElementView", "ModelView", "element_stl", "model_view"]


@dataclass(frozen=True)
class ElementView:
    """One collision element: its link, its pose there (x, y, z, qx, qy, qz, qw), its shape."""

    link: int
    origin: list[float]
    kind: str
    size: list[float]
    mesh: int | None  # index of the element, whose STL file holds the mesh
    triangles: int | None


@dataclass(frozen=True)
class ModelView:
    """The links of a model and the collision elements they carry."""

    model_id: str
    name: str
    base: str
    state_names: list[str]
    link_names: list[str]
    end_effector_link: int
    elements: list[ElementView]


def model_view(*, session: Session, registry: ModelRegistry, model_id: str) -> ModelView:
    """The geometry of model `model_id` as the view draws it."""
    model = get_model(session=session, registry=registry, model_id=model_id)
    return describe_model(model)


def describe_model(model: RobotModel) -> ModelView:
    """`model`'s links and collision elements (see the module docstring)."""
    elements = []
    for index, element in enumerate(model.elements):
        shape = element.shape
        mesh = shape.kind is ShapeKind.MESH
        elements.append(
            ElementView(
                link=element.link,
                origin=[round(float(v), 7) for v in pose7(element.origin)],
                kind=shape.kind.value,
                size=[float(v) for v in shape.size],
                mesh=index if mesh else None,
                triangles=len(shape.faces) if mesh and shape.faces is not None else None,
            )
        )
    return ModelView(
        model_id=model.model_id,
        name=model.name,
        base=model.base.value,
        state_names=list(model.state_names),
        link_names=list(model.link_names),
        end_effector_link=end_effector_link(model),
        elements=elements,
    )


def element_stl(*, session: Session, registry: ModelRegistry, model_id: str, element: int) -> bytes:
    """The triangles of mesh element `element` of model `model_id`, as binary STL."""
    model = get_model(session=session, registry=registry, model_id=model_id)
    if not 0 <= element < len(model.elements):
        raise NotFoundError(
            f"robot model {model_id!r} has no collision element {element} "
            f"(it has {len(model.elements)})"
        )
    shape = model.elements[element].shape
    if shape.kind is not ShapeKind.MESH or shape.vertices is None or shape.faces is None:
        raise NotFoundError(
            f"collision element {element} of robot model {model_id!r} is a {shape.kind.value}, "
            "not a mesh"
        )
    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    data: bytes = trimesh.exchange.stl.export_stl(mesh)
    return data
