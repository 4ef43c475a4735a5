"""The store of Cartesian path answers (`services.cartesian.store` reads and writes it)."""

from __future__ import annotations

from sqlalchemy import JSON, ForeignKey, Index, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from trajcache.db.base import Base


class CartesianPathRow(Base):
    """A Cartesian path answered whole (fraction 1.0): the request it answered (model, link,
    a digest of the parameters, waypoints, start) and its joint path."""

    __tablename__ = "cartesian_paths"
    __table_args__ = (
        Index("ix_cartesian_paths_model_id_link_params", "model_id", "link", "params"),
        {"sqlite_autoincrement": True},
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    model_id: Mapped[str] = mapped_column(
        String(64), ForeignKey("robot_models.id", ondelete="CASCADE")
    )
    link: Mapped[str] = mapped_column(String(200))
    params: Mapped[str] = mapped_column(String(64))  # digest of the steps, thresholds, tolerances
    waypoints: Mapped[list[list[float]]] = mapped_column(JSON)  # [x, y, z, qx, qy, qz, qw] each
    start: Mapped[list[float]] = mapped_column(JSON)
    states: Mapped[list[list[float]]] = mapped_column(JSON)  # the joint path, start first
    line_of: Mapped[list[int]] = mapped_column(JSON)  # the line each state was solved on
