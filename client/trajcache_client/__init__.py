"""Python client of the trajcache planning service.

from trajcache_client import Client

with Client("http://127.0.0.1:8000") as tc:
    answer = tc.plan("r1", start, goal)
"""

from trajcache_client._admin_models import (
    ImportResult,
    ModelPrune,
    PruneResult,
    RejectedLine,
    SeedJob,
    SeedJobError,
)
from trajcache_client._async_client import AsyncClient
from trajcache_client._base import DEFAULT_BASE_URL, DEFAULT_RETRY, DEFAULT_TIMEOUT
from trajcache_client._client import Client
from trajcache_client._exceptions import (
    APIError,
    AuthError,
    BadRequestError,
    ConflictError,
    NotFoundError,
    PayloadTooLargeError,
    ServerError,
    TrajcacheError,
    TransportError,
    TransportTimeoutError,
    UnavailableError,
    UnexpectedResponseError,
    UnsupportedMediaTypeError,
    ValidationError,
)
from trajcache_client._models import (
    Health,
    JointTrajectory,
    JointTrajectoryPoint,
    ModelFile,
    Page,
    PlanEvent,
    PlanOptions,
    PlanResult,
    Rejection,
    Robot,
    RobotModel,
    RobotModelDetail,
    RobotModelSummary,
    Scene,
    SceneVersion,
    SkippedPair,
    TimingOptions,
    Trajectory,
    TrajectoryCreated,
    TrajectoryQuality,
    TrajectorySummary,
)
from trajcache_client._moveit_models import MotionPlanResponse
from trajcache_client._operations import Operation
from trajcache_client._retry import NO_RETRY, Retry
from trajcache_client._stats_models import (
    Latency,
    Metrics,
    ModelBasis,
    PlanEventPage,
    Stats,
    StatsBucket,
    StatsGroup,
    TopTrajectory,
)
from trajcache_client._version import __version__

__all__ = [
    "DEFAULT_BASE_URL",
    "DEFAULT_RETRY",
    "DEFAULT_TIMEOUT",
    "NO_RETRY",
    "APIError",
    "AsyncClient",
    "AuthError",
    "BadRequestError",
    "Client",
    "ConflictError",
    "Health",
    "ImportResult",
    "JointTrajectory",
    "JointTrajectoryPoint",
    "Latency",
    "Metrics",
    "ModelBasis",
    "ModelFile",
    "ModelPrune",
    "MotionPlanResponse",
    "NotFoundError",
    "Operation",
    "Page",
    "PayloadTooLargeError",
    "PlanEvent",
    "PlanEventPage",
    "PlanOptions",
    "PlanResult",
    "PruneResult",
    "RejectedLine",
    "Rejection",
    "Retry",
    "Robot",
    "RobotModel",
    "RobotModelDetail",
    "RobotModelSummary",
    "Scene",
    "SceneVersion",
    "SeedJob",
    "SeedJobError",
    "ServerError",
    "SkippedPair",
    "Stats",
    "StatsBucket",
    "StatsGroup",
    "TimingOptions",
    "TopTrajectory",
    "TrajcacheError",
    "Trajectory",
    "TrajectoryCreated",
    "TrajectoryQuality",
    "TrajectorySummary",
    "TransportError",
    "TransportTimeoutError",
    "UnavailableError",
    "UnexpectedResponseError",
    "UnsupportedMediaTypeError",
    "ValidationError",
    "__version__",
]
