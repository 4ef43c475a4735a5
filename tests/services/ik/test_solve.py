"""The IK service's pure parts: cached endpoints as starts, and the link a request names."""

from __future__ import annotations

import numpy as np
import pytest

from tests.robots import PINCER_SRDF, PINCER_URDF
from trajcache.geometry.model.ik import PoseTarget
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.robot import STOWED_ARM, reference_model
from trajcache.services.errors import InvalidInputError
from trajcache.services.ik.solve import CACHED_STARTS, IkRequest, cached_starts, link_of


def test_cached_endpoints_nearest_the_target_come_first_on_the_seeds_base() -> None:
    model = reference_model()
    rng = np.random.default_rng(4)
    endpoints = np.repeat(np.array([[0.0, 0.0, 0.0, *STOWED_ARM]]), 40, axis=0)
    endpoints[:, 3:] = rng.uniform(model.lower[3:], model.upper[3:], (40, 7))
    endpoints[:, :3] = rng.uniform(-3.0, 3.0, (40, 3))  # wherever those robots stood
    seed = np.array([1.0, 2.0, 0.5, *STOWED_ARM])
    on_seed_base = endpoints.copy()
    on_seed_base[:, :3] = seed[:3]
    tool = model.link_names.index("tool_tip")
    poses = link_transforms(model, on_seed_base)[:, tool]
    target = PoseTarget("tool_tip", poses[17])
    starts = cached_starts(model, endpoints, seed, target, move_base=False)
    assert len(starts) == CACHED_STARTS
    np.testing.assert_allclose(starts[0], on_seed_base[17])
    gaps = [
        np.linalg.norm(link_transforms(model, s)[0, tool, :3, 3] - poses[17][:3, 3]) for s in starts
    ]
    assert gaps == sorted(gaps)
    assert cached_starts(model, endpoints[:0], seed, target, move_base=False) == []
    moved = cached_starts(model, endpoints, seed, target, move_base=True)
    assert all(any(np.array_equal(s, e) for e in endpoints) for s in moved)


def _request(link: str) -> IkRequest:
    return IkRequest(link=link, position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0))


def test_a_request_names_a_link_an_end_effector_or_none() -> None:
    srdf = PINCER_SRDF.replace(
        "</robot>", '<end_effector name="gripper" parent_link="upper" group="arm"/></robot>'
    )
    model = load_robot_model(PINCER_URDF, srdf=srdf)
    assert link_of(model, srdf, _request("upper").link) == "upper"
    assert link_of(model, srdf, _request("gripper").link) == "upper"
    assert link_of(model, srdf, _request("").link) in model.link_names
    with pytest.raises(
        InvalidInputError, match=r"link: 'claw' is neither .* gripper \(end effector\)"
    ):
        link_of(model, srdf, _request("claw").link)
