"""MoveIt's planning messages over HTTP: a MotionPlanRequest in, a MotionPlanResponse out.

The request becomes the native plan request (`services.plan.flow.PlanRequest`) and the native
answer a MotionPlanResponse; the plan flow itself is the native endpoint's. A well-formed request
is always answered, with MoveIt's error code saying whether it succeeded (`_codes`); malformed or
unsupported requests are 422s (`_body`, `_messages`).
"""

from __future__ import annotations

from trajcache.api.moveit._body import (
    RawBody,
    RawBodyDep,
    inlined_schema,
    is_supported,
    parse_motion_plan_request,
    read_document,
    validated,
)
from trajcache.api.moveit._cartesian import (
    CartesianQuery,
    GetCartesianPathIn,
    GetCartesianPathOut,
    cartesian_query,
    cartesian_response,
)
from trajcache.api.moveit._codes import (
    MotionPlanError,
    MoveItErrorCode,
    answer_code,
    state_error_code,
)
from trajcache.api.moveit._either import answer_either, either_body
from trajcache.api.moveit._ik import (
    GetPositionIKIn,
    GetPositionIKOut,
    IkQuery,
    ik_query,
    ik_response,
)
from trajcache.api.moveit._ik import answer_code as ik_answer_code
from trajcache.api.moveit._messages import (
    MotionPlanRequestIn,
    Quaternion,
    Vector3,
    native_planner,
)
from trajcache.api.moveit._request import MotionPlanQuery, motion_plan_query
from trajcache.api.moveit._response import answered_body, refused_body
from trajcache.api.moveit._schemas import MotionPlanResponseOut

__all__ = [
    "CartesianQuery",
    "GetCartesianPathIn",
    "GetCartesianPathOut",
    "GetPositionIKIn",
    "GetPositionIKOut",
    "IkQuery",
    "MotionPlanError",
    "MotionPlanQuery",
    "MotionPlanRequestIn",
    "MotionPlanResponseOut",
    "MoveItErrorCode",
    "Quaternion",
    "RawBody",
    "RawBodyDep",
    "Vector3",
    "answer_code",
    "answer_either",
    "answered_body",
    "cartesian_query",
    "cartesian_response",
    "either_body",
    "ik_answer_code",
    "ik_query",
    "ik_response",
    "inlined_schema",
    "is_supported",
    "motion_plan_query",
    "native_planner",
    "parse_motion_plan_request",
    "read_document",
    "refused_body",
    "state_error_code",
    "validated",
]
