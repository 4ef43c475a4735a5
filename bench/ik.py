"""Inverse kinematics solvers on random reachable poses: which one the service uses, and why.

Robots: the MotionBenchMaker Panda (`../shared/data/mbm-panda/robot/`, else example-robot-data's
Panda; its arm group, target `panda_hand`) and the reference robot (`tool_tip`, the base held
still). For each robot, --poses random states within the limits give the targets (the link's
pose there); each solver starts from the robot's ready state (the SRDF's `ready`, or the
reference robot's stowed arm), then random restarts, within a 50 ms budget, at 1 mm and 0.01 rad.

Solvers:
- `dls`: the service's damped least squares (`trajcache.geometry.model.ik`), first solution;
- `dls-3`: the same, the nearest of 3 solutions (the IK route's default);
- `pink`: `pin-pink` (a QP per step with daqp, limits as constraints), first solution, with the
  same restarts; skipped when pin-pink is not installed.

Every answer's pose is checked independently with yourdfpy's forward kinematics (not
Pinocchio): `pose_errors` counts answers off by more than the tolerances. Prints a table; the
last line is one JSON object: per robot and solver `success_rate`, `ms_median`, `ms_p95`,
`pose_errors`, and the headline `success_rate`, `ms_median`, `ms_p95` of `dls` over all.

    python bench/ik.py [--smoke] [--poses N] [--solvers dls,dls-3,pink]
"""

from __future__ import annotations

import argparse
import io
import json
import logging
import math
import re
import statistics
import sys
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from yourdfpy import URDF
from yourdfpy.urdf import filename_handler_null

from trajcache.geometry.model.ik import IkProblem, IkStatus, PoseTarget, solve_ik
from trajcache.geometry.model.kinematics import link_transforms
from trajcache.geometry.model.pin_kinematics import PinKinematics
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.reference.example_robots import ROBOTS
from trajcache.reference.robot import STOWED_ARM, reference_model, reference_urdf

MBM_ROBOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "mbm-panda" / "robot"
POSITION_TOLERANCE, ORIENTATION_TOLERANCE = 1e-3, 1e-2
BUDGET_S = 0.05
SolveFn = Callable[["Case", np.ndarray, np.ndarray], "np.ndarray | None"]


@dataclass(frozen=True)
class Case:
    """A robot to solve for: its model, URDF, target link and seed state."""

    name: str
    model: RobotModel
    urdf: str
    link: str
    seed: np.ndarray
    kinematics: PinKinematics
    srdf: str | None = None  # what registers it with the service (--service)
    group: str | None = None
    files: dict[str, bytes] = field(default_factory=dict)


def cases() -> list[Case]:
    """The Panda (MBM's, else example-robot-data's) and the reference robot."""
    if (MBM_ROBOT / "panda.urdf").is_file():
        urdf, srdf = (MBM_ROBOT / "panda.urdf").read_text(), (MBM_ROBOT / "panda.srdf").read_text()
        files = {
            f"meshes/collision/{path.name}": path.read_bytes()
            for path in (MBM_ROBOT / "meshes" / "collision").iterdir()
        }
        group = "panda_arm"
    else:
        robot = ROBOTS["panda"]
        urdf, srdf, files, group = robot.urdf, robot.srdf, robot.files(), str(robot.group)
    panda = load_robot_model(urdf, files=files, srdf=srdf, group=group, name="panda")
    ready = np.array(panda.named_states.get("ready", np.zeros(panda.dof)))
    reference = reference_model()
    seed = np.array([0.0, 0.0, 0.0, *STOWED_ARM])
    return [
        Case(
            "panda",
            panda,
            urdf,
            "panda_hand",
            ready,
            PinKinematics.build(panda, urdf),
            srdf=srdf,
            group=group,
            files=files,
        ),
        Case(
            "reference",
            reference,
            reference_urdf(),
            "tool_tip",
            seed,
            PinKinematics.build(reference, reference_urdf()),
        ),
    ]


def targets(case: Case, count: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Poses of the link at random states within the limits (the base at the seed's)."""
    states = np.repeat(case.seed[None], count, axis=0)
    arm = slice(case.model.arm_offset, case.model.dof)
    states[:, arm] = rng.uniform(case.model.lower[arm], case.model.upper[arm], (count, 7))
    link = case.model.link_names.index(case.link)
    return list(link_transforms(case.model, states)[:, link])


def dls(solutions: int) -> SolveFn:
    """The service's solver, answering the nearest of `solutions`."""

    def solve(case: Case, pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        target = PoseTarget(case.link, pose, POSITION_TOLERANCE, ORIENTATION_TOLERANCE)
        problem = IkProblem(
            case.kinematics, target, seed, solutions=solutions, budget_s=BUDGET_S, rng_seed=1
        )
        result = solve_ik(problem)
        return result.state if result.status is IkStatus.SUCCESS else None

    return solve


def pink_solver() -> SolveFn:
    """pin-pink's differential IK (QP per step), restarted like the service's solver."""
    import pink
    from pink.tasks import FrameTask

    reduced: dict[str, tuple[Any, list[int]]] = {}

    def arm_model(case: Case) -> tuple[Any, list[int]]:
        if case.name not in reduced:  # the arm alone, the base and held joints locked
            full = pin.buildModelFromXML(case.urdf)
            names = case.model.joint_names
            lock = [j for j in range(1, full.njoints) if full.names[j] not in names]
            model = pin.buildReducedModel(full, lock, pin.neutral(full))
            reduced[case.name] = (model, [model.joints[model.getJointId(n)].idx_q for n in names])
        return reduced[case.name]

    def solve(case: Case, pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        model, index = arm_model(case)
        off, ends = case.model.arm_offset, time.perf_counter() + BUDGET_S
        rng, target = np.random.default_rng(1), pin.SE3(pose)
        start = seed[off:].copy()
        while time.perf_counter() < ends:
            q = pin.neutral(model)
            q[index] = start
            config = pink.Configuration(model, model.createData(), q)
            task = FrameTask(case.link, position_cost=1.0, orientation_cost=1.0)
            task.set_target(target)
            for _ in range(80):
                current = config.get_transform_frame_to_world(case.link)
                err = current.actInv(target)
                position = np.linalg.norm(err.translation)
                orientation = np.linalg.norm(pin.log3(err.rotation))
                if position <= POSITION_TOLERANCE / 2 and orientation <= ORIENTATION_TOLERANCE / 2:
                    state = seed.copy()
                    state[off:] = config.q[index]
                    return state
                velocity = pink.solve_ik(config, [task], 1.0, solver="daqp", damping=1e-6)
                config.integrate_inplace(velocity, 1.0)
            start = rng.uniform(case.model.lower[off:], case.model.upper[off:])
        return None

    return solve


def yourdfpy_robot(case: Case) -> Any:
    """yourdfpy's model of the case's URDF (kinematics only), for the independent check."""
    text = re.sub(r"^\s*<\?xml[^>]*\?>", "", case.urdf.strip()).encode()
    return URDF.load(
        io.BytesIO(text),
        build_scene_graph=True,
        load_meshes=False,
        filename_handler=filename_handler_null,
    )


def independent_error(reference: Any, case: Case, state: np.ndarray, pose: np.ndarray) -> bool:
    """Whether yourdfpy puts the link farther from `pose` than the tolerances."""
    cfg = dict(zip(case.model.joint_names, state[case.model.arm_offset :], strict=True))
    reference.update_cfg({n: float(v) for n, v in cfg.items()})
    root = case.model.link_names[0]
    got = reference.get_transform(case.link, root)
    if case.model.arm_offset:  # the planar base: x, y, θ of the state
        x, y, theta = state[:3]
        base = np.eye(4)
        base[:2, :2] = ((math.cos(theta), -math.sin(theta)), (math.sin(theta), math.cos(theta)))
        base[:2, 3] = (x, y)
        got = base @ got
    position = float(np.linalg.norm(got[:3, 3] - pose[:3, 3]))
    cos = (np.trace(got[:3, :3].T @ pose[:3, :3]) - 1.0) / 2.0
    angle = math.acos(min(1.0, max(-1.0, cos)))
    return position > POSITION_TOLERANCE or angle > ORIENTATION_TOLERANCE


def run(case: Case, solve: SolveFn, poses: list[np.ndarray]) -> dict[str, Any]:
    """Figures of one solver on one robot."""
    reference = yourdfpy_robot(case)
    times, solved, errors = [], 0, 0
    for pose in poses:
        began = time.perf_counter()
        state = solve(case, pose, case.seed)
        times.append((time.perf_counter() - began) * 1e3)
        if state is not None:
            solved += 1
            errors += independent_error(reference, case, state, pose)
    ordered = sorted(times)
    return {
        "success_rate": round(solved / len(poses), 4),
        "ms_median": round(statistics.median(ordered), 3),
        "ms_p95": round(ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))], 3),
        "pose_errors": errors,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="20 poses per robot")
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--solvers", default="dls,dls-3,pink")
    parser.add_argument(
        "--service", action="store_true", help="also through a live service's POST /ik"
    )
    args = parser.parse_args()
    logging.disable(logging.WARNING)  # yourdfpy warns of each held mimic joint on every update
    count = 20 if args.smoke else args.poses
    robots = cases()
    with ExitStack() as stack:
        solvers = _solvers(args.solvers.split(","), robots, stack if args.service else None)
        figures = _table(robots, solvers, count)
    headline = [figures[k] for k in figures if k.endswith("/dls")]
    summary = {
        "success_rate": min(r["success_rate"] for r in headline),
        "ms_median": max(r["ms_median"] for r in headline),
        "ms_p95": max(r["ms_p95"] for r in headline),
        "pose_errors": sum(r["pose_errors"] for r in figures.values()),
        "poses": count,
        "solvers": figures,
    }
    print(json.dumps(summary))
    return 0 if summary["pose_errors"] == 0 else 1


def _solvers(names: list[str], robots: list[Case], stack: ExitStack | None) -> dict[str, SolveFn]:
    """The solvers asked for (pin-pink when installed; the live service with a stack)."""
    solvers: dict[str, SolveFn] = {"dls": dls(1), "dls-3": dls(3)}
    if "pink" in names:
        try:
            solvers["pink"] = pink_solver()
        except ImportError:
            print("pin-pink is not installed: its row is skipped", file=sys.stderr)
    chosen = {name: solvers[name] for name in names if name in solvers}
    if "dls" not in chosen:
        chosen = {"dls": solvers["dls"], **chosen}  # the headline's
    if stack is not None:
        from ik_service import ServiceSolver

        chosen["service"] = ServiceSolver(robots, stack)
    return chosen


def _table(robots: list[Case], solvers: dict[str, SolveFn], count: int) -> dict[str, Any]:
    """Each solver's row per robot, printed as they come."""
    figures: dict[str, Any] = {}
    print(
        f"{'robot':<10} {'solver':<7} {'solved':>7} {'median ms':>10} {'p95 ms':>8} {'errors':>7}"
    )
    for case in robots:
        poses = targets(case, count, np.random.default_rng(7))
        for name, solve in solvers.items():
            server_ms = getattr(solve, "server_ms", None)
            statuses = getattr(solve, "statuses", None)
            if server_ms is not None and statuses is not None:
                server_ms.clear()
                statuses.clear()
            row = run(case, solve, poses)
            if server_ms:
                row["server_ms_median"] = round(statistics.median(server_ms), 3)
                row["statuses"] = dict(statuses or {})
            figures[f"{case.name}/{name}"] = row
            print(
                f"{case.name:<10} {name:<7} {row['success_rate']:>7.1%} {row['ms_median']:>10.3f}"
                f" {row['ms_p95']:>8.3f} {row['pose_errors']:>7}"
            )
    return figures


if __name__ == "__main__":
    sys.exit(main())
