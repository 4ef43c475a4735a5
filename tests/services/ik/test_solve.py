"""The IK service's pure parts: the link a request names."""

from __future__ import annotations

import pytest

from tests.robots import PINCER_SRDF, PINCER_URDF
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.services.errors import InvalidInputError
from trajcache.services.ik.solve import IkRequest, link_of


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
