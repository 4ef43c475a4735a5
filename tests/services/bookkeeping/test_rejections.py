"""A request's rejected candidates: one list, read for the ids, the answer and reused verdicts."""

from __future__ import annotations

import numpy as np

from trajcache.geometry.validation.validator import ValidationResult, ValidationStatus
from trajcache.services.bookkeeping.rejections import RejectedCandidate, Rejections

PATH = np.array([[0.0, 0.0], [1.0, 0.5]])
OTHER = np.array([[0.0, 0.0], [0.5, 1.0]])


def _result(status: ValidationStatus, message: str) -> ValidationResult:
    return ValidationResult(status, samples=4, narrow_checks=1, message=message)


def test_an_empty_list_rejects_nothing() -> None:
    rejections = Rejections()
    assert not rejections and len(rejections) == 0
    assert rejections.ids() == () and rejections.listed() == []
    assert rejections.verdict(PATH) is None


def test_the_list_keeps_the_order_tried_and_gives_each_reading() -> None:
    collided = _result(ValidationStatus.COLLISION, "link upper hits ball")
    limits = _result(ValidationStatus.OUT_OF_LIMITS, "elbow beyond its limit")
    rejections = Rejections()
    rejections.add(RejectedCandidate(7, False, PATH, collided))
    rejections.add(RejectedCandidate(3, True, OTHER, limits))
    rejections.add(RejectedCandidate(5, False, PATH.copy(), collided))  # the same path, reused
    assert rejections and len(rejections) == 3
    assert rejections.ids() == (7, 3, 5)
    assert [r.trajectory_id for r in rejections] == [7, 3, 5]
    assert rejections.listed()[:2] == [
        {"trajectory_id": 7, "status": "collision", "reason": "link upper hits ball"},
        {"trajectory_id": 3, "status": "out_of_limits", "reason": "elbow beyond its limit"},
    ]
    assert rejections.verdict(PATH.copy()) is collided
    assert rejections.verdict(OTHER) is limits
    assert rejections.verdict(PATH[::-1]) is None
