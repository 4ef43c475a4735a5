"""What certifying segments works on and finds: the pairs left open, and where it stopped."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from trajcache.geometry.collision.checker import Contact
from trajcache.geometry.model.shapes import FloatArray

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


class SegmentStatus(str, Enum):
    """What certifying the segments of a piece of trajectory found."""

    FREE = "free"
    COLLISION = "collision"
    TOO_CLOSE = "too_close"


@dataclass
class Finding:
    """Where certification stopped: segment `segment` at fraction `at`, and the pairs involved."""

    status: SegmentStatus
    segment: int = -1
    at: float = 0.0
    contacts: list[Contact] = field(default_factory=list)
    subdivisions: int = 0  # probe states conservative advancement looked at

    @property
    def position(self) -> float:
        """Position along the samples (segment + fraction), for picking the earliest finding."""
        return self.segment + self.at if self.segment >= 0 else np.inf


@dataclass
class OpenPairs:
    """Pairs left open on segments: rows at the segment start, distance lower bounds at both
    ends and a bound on the pair's relative motion over the segment."""

    scene: bool
    rows: IntArray  # (K, 3) (segment, element, object) or (K, 2) (segment, pair)
    lower_a: FloatArray  # (K,)
    lower_b: FloatArray
    motion: FloatArray  # (K,) bound on the relative motion of any point over the segment

    def take(self, keep: BoolArray) -> OpenPairs:
        """The pairs where `keep` is True."""
        return OpenPairs(
            self.scene, self.rows[keep], self.lower_a[keep], self.lower_b[keep], self.motion[keep]
        )

    def open(self) -> OpenPairs:
        """The pairs their bounds do not certify."""
        return self.take(self.lower_a + self.lower_b <= self.motion)

    @property
    def ends(self) -> IntArray:
        """The rows moved to the segment's end sample."""
        shift = np.zeros(self.rows.shape[1], dtype=np.int64)
        shift[0] = 1
        return self.rows + shift


@dataclass(frozen=True)
class MovingPoints:
    """Points at_a → at_b (K, S, 3) of elements, their lever coefficients and ball radii."""

    at_a: FloatArray
    at_b: FloatArray
    coef: FloatArray
    radius: FloatArray


_FEW_ROWS = 256  # rows made unique in Python; numpy's sort of row views costs more below it


def unique_rows(rows: IntArray) -> tuple[IntArray, IntArray]:
    """`np.unique(rows, axis=0, return_inverse=True)`: the distinct rows in lexicographic order,
    and the index of each row among them. The few rows a bound level leaves open go through
    Python's sort, which is several times quicker on them than numpy's."""
    if len(rows) > _FEW_ROWS:
        unique, where = np.unique(rows, axis=0, return_inverse=True)
        return unique, where.reshape(-1)
    listed = [tuple(row) for row in rows.tolist()]
    ordered = sorted(set(listed))
    at = {row: i for i, row in enumerate(ordered)}
    unique = np.array(ordered, dtype=np.int64).reshape(len(ordered), rows.shape[1])
    return unique, np.fromiter((at[row] for row in listed), dtype=np.int64, count=len(listed))
