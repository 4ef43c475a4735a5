"""The MotionBenchMaker Panda problems as shipped: MoveIt's scene and request YAML, untouched.

The robot is registered as a team ships it (URDF, SRDF group `panda_arm`, its collision meshes
zipped as the URDF's `package://` URIs name them); each family's first problem's scene is PUT as
is, and its MotionPlanRequest POSTed as is. Every answer is a MoveIt answer (200, success or a
planning failure code), never a refusal: unknown `BKPIECEGood` planner ids, a 60 s budget, the
fixed finger joints in the start state, lists for vectors and quaternions are all read as MoveIt
clients mean them, with warnings. Skipped when the data set is not there.
"""

from __future__ import annotations

import base64
import io
import tarfile
import zipfile
from pathlib import Path

import pytest

from tests.api.conftest import ClientFactory
from trajcache.api.moveit import MotionPlanResponseOut, MoveItErrorCode

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "mbm-panda"
FAMILIES = ("bookshelf_small", "bookshelf_tall", "bookshelf_thin", "box", "cage", "table_pick",
            "table_under_pick")  # fmt: skip
# Outcomes a planner may come to within a small budget; anything else is a refusal.
PLANNED = {MoveItErrorCode.SUCCESS, MoveItErrorCode.PLANNING_FAILED, MoveItErrorCode.TIMED_OUT,
           MoveItErrorCode.INVALID_MOTION_PLAN}  # fmt: skip
YAML = {"content-type": "application/yaml"}

pytestmark = pytest.mark.skipif(not DATA.is_dir(), reason=f"no MBM data set at {DATA}")


def _problems() -> dict[str, tuple[str, str]]:
    """Each family's first problem: (scene text, request text), read from the tarball."""
    out: dict[str, tuple[str, str]] = {}
    with tarfile.open(DATA / "problems.tar.bz2", "r:bz2") as archive:
        for family in FAMILIES:
            texts = []
            for kind in ("scene", "request"):
                member = archive.extractfile(f"problems/{family}_panda/{kind}0001.yaml")
                assert member is not None
                texts.append(member.read().decode("utf-8"))
            out[family] = (texts[0], texts[1])
    return out


def _meshes(robot_dir: Path) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted((robot_dir / "meshes").rglob("*")):
            if path.is_file():
                archive.writestr(str(path.relative_to(robot_dir)), path.read_bytes())
    return buffer.getvalue()


def test_mbm_scenes_and_requests_are_accepted_as_shipped(client_factory: ClientFactory) -> None:
    client = client_factory(worker_processes=1, plan_budget_s=0.5, plan_budget_max_s=0.5)
    robot_dir = DATA / "robot"
    registered = client.post(
        "/v1/robot-models",
        json={
            "urdf": (robot_dir / "panda.urdf").read_text(encoding="utf-8"),
            "srdf": (robot_dir / "panda.srdf").read_text(encoding="utf-8"),
            "group": "panda_arm",
            "archive_base64": base64.b64encode(_meshes(robot_dir)).decode("ascii"),
        },
    )
    assert registered.status_code in (200, 201), registered.text
    model_id = registered.json()["model_id"]
    for family, (scene, request) in _problems().items():
        robot = f"mbm-{family}"
        assert client.put(f"/v1/robots/{robot}", json={"model_id": model_id}).status_code == 201
        put = client.put(f"/v1/robots/{robot}/scene", content=scene, headers=YAML)
        assert put.status_code == 200, f"{family} scene: {put.text}"
        reply = client.post(f"/v1/robots/{robot}/motion-plan", content=request, headers=YAML)
        assert reply.status_code == 200, f"{family} request: {reply.text}"
        answer = MotionPlanResponseOut.model_validate(reply.json())
        assert MoveItErrorCode(answer.error_code.val) in PLANNED, (family, answer.error_code)
        warnings = " | ".join(answer.warnings)
        for needle in ("'BKPIECEGood'", "allowed_planning_time 60", "panda_finger_joint1"):
            assert needle in warnings, (family, warnings)
