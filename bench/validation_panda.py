"""The validation benchmark's Panda row: the certified validator on a robot with meshes.

The Panda of `example-robot-data` as shipped (URDF with its meshes, SRDF, group "arm"), in the
seeded table, shelf, box and cage problems of `scene_families` (collision-free start and goal).
Each problem gives up to three paths (`panda_paths`: straight, detour and grazing). On every
path:

- the certified validator, `TrajectoryValidator(model, scene).validate(key_states)`, warm (a
  cache hit finds its validator built; building it and validating the first path of a scene is
  timed apart, `panda_first_call_ms_p50`); also the plain validator (`certified=False`);
- the naive per-state FCL loop (`naive_fcl.NaiveChecker`) and its pairs-only variant
  (`naive_fcl.PairChecker`) over the same samples, each stopping at the first collision;
- the independent dense check (`dense_mesh.MeshChecker`: Pinocchio and coal on the meshes, steps
  4× finer than the paper's, no padding), stopping at the first sample in contact.

A path the validator accepts is a mismatch (a safety failure) when the dense check or a naive
sample finds it in collision. A path it rejects that the dense check finds free is a
conservative rejection, counted by reason: "passes closer than can be certified" with the link
and the kind of object (ids without their numbers), or a collision the dense check confirms at
the validator's state (it lies between the dense samples) or does not.

Rates and ratios are over every path's samples at the validator's resolution and the summed
times (a checker stops at the first collision); per-path times are medians over the paths.
"""

from __future__ import annotations

import re
import statistics
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dense_mesh import FloatArray, MeshChecker
from naive_fcl import NaiveChecker, PairChecker, timed_runs
from panda_paths import KINDS, dense_collides, paths_of
from robot_description import describe
from scene_families import FAMILIES, Problem, Workspace, generate_problem, workspace
from trajcache.geometry.collision.checker import ContactKind
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.urdf import load_robot_model
from trajcache.geometry.scene.parse import parse_scene
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.validation.validator import (
    Resolution,
    TrajectoryValidator,
    ValidationResult,
    ValidationStatus,
    interpolate,
)
from trajcache.reference.example_robots import ROBOTS

_NUMBERED = re.compile(r"(_[+-]?\d+)+$")


@dataclass
class PathTiming:
    """One path's samples, verdicts and median times (s)."""

    kind: str  # of KINDS
    samples: int
    status: ValidationStatus
    naive: float
    pairs: float
    plain: float
    numpy: float  # the certified validator on its numpy levels (`compiled=False`)
    certified: float


@dataclass
class PandaTally:
    """What the Panda's paths gave."""

    paths: list[PathTiming] = field(default_factory=list)
    problems: int = 0
    skipped: int = 0  # problems without a free start and goal
    dense_samples: int = 0
    first_call: list[float] = field(default_factory=list)  # validator built + first path (s)
    mismatches: int = 0
    naive_disagreements: int = 0  # paths the two naive loops judge differently
    numpy_only: int = 0  # paths the numpy levels certify and the compiled ones do not
    conservative: Counter[str] = field(default_factory=Counter)


def panda_model() -> tuple[RobotModel, MeshChecker]:
    """The service's model of the Panda as shipped, and the dense check of the same robot."""
    robot = ROBOTS["panda"]
    model = load_robot_model(robot.urdf, files=robot.files(), srdf=robot.srdf, group="arm")
    held = dict(model.held_values)
    return model, MeshChecker(describe(robot, joint_names=model.joint_names, held=held))


def rejection_reason(result: ValidationResult, dense: MeshChecker) -> str:
    """Why the validator rejected a path the dense check finds free, without sample numbers."""
    if result.status is ValidationStatus.TOO_CLOSE:
        near = sorted(
            {
                f"{c.link} near {_NUMBERED.sub('', c.other)}"
                if c.kind is ContactKind.SCENE
                else f"{c.link} near {c.other}"
                for c in result.contacts
            }
        )
        return f"passes closer than can be certified: {', '.join(near)}"
    if result.status is ValidationStatus.COLLISION:
        assert result.state is not None
        confirmed = not dense.is_free(result.state)
        return (
            "collision between the dense samples (the dense check confirms its state)"
            if confirmed
            else "collision the dense check does not confirm at its state"
        )
    return f"{result.status.value}: {result.message[:80]}"


def problems(
    dense: MeshChecker, ws: Workspace, per_family: int, seed: int, tally: PandaTally
) -> Iterator[tuple[Problem, list[tuple[str, FloatArray]]]]:
    """Each problem with its (kind, key states) paths; leaves `dense` set to its scene."""
    for family in FAMILIES:
        for index in range(per_family):
            problem = generate_problem(dense, ws, family, index, seed)
            if problem is None:
                tally.skipped += 1
                continue
            tally.problems += 1
            rng = np.random.default_rng([seed, 7, FAMILIES.index(family), index])
            yield problem, paths_of(dense, ws, problem, rng)


@dataclass
class SceneCheckers:
    """Every checker of one problem's scene; the dense check must hold the same scene."""

    model: RobotModel
    certified: TrajectoryValidator
    plain: TrajectoryValidator
    numpy: TrajectoryValidator
    naive: NaiveChecker
    pairs: PairChecker
    dense: MeshChecker

    def measure(self, kind: str, key: FloatArray, repeats: int, tally: PandaTally) -> None:
        """Time one path on every checker, dense-check it and tally the verdicts."""
        samples = interpolate(key, self.model, Resolution())
        times, verdicts = timed_runs(
            [
                lambda: self.naive.validate(samples),
                lambda: self.pairs.validate(samples),
                lambda: self.plain.validate(key),
                lambda: self.numpy.validate(key),
                lambda: self.certified.validate(key),
            ],
            repeats,
        )
        naive_free, pairs_free, _, numpy_result, result = verdicts
        assert isinstance(numpy_result, ValidationResult)
        if numpy_result.valid and not result.valid:
            tally.numpy_only += 1
        assert isinstance(result, ValidationResult)
        tally.naive_disagreements += naive_free != pairs_free
        collides, checked = dense_collides(self.dense, key)
        tally.dense_samples += checked
        if result.valid and (collides or not naive_free):
            tally.mismatches += 1
        elif not result.valid and not collides:
            tally.conservative[f"{kind}: {rejection_reason(result, self.dense)}"] += 1
        tally.paths.append(PathTiming(kind, len(samples), result.status, *times))


def run_panda(per_family: int, seed: int, repeats: int) -> PandaTally:
    """Validate, time and dense-check the Panda's paths."""
    model, dense = panda_model()
    ws = workspace(dense, seed, model.lower, model.upper)
    tally = PandaTally()
    for problem, paths in problems(dense, ws, per_family, seed, tally):
        scene = parse_scene({"objects": list(problem.objects)})
        began = time.perf_counter()
        certified = TrajectoryValidator(model, scene)
        certified.validate(paths[0][1])  # what the first path after a scene change pays
        tally.first_call.append(time.perf_counter() - began)
        plain = TrajectoryValidator(model, scene, certified=False)
        numpy = TrajectoryValidator(model, scene, certifier=CertifierOptions(compiled=False))
        checkers = SceneCheckers(
            model,
            certified,
            plain,
            numpy,
            NaiveChecker(model, scene),
            PairChecker(model, scene),
            dense,
        )
        for kind, key in paths:
            checkers.measure(kind, key, repeats, tally)
    return tally


def groups(tally: PandaTally) -> dict[str, list[PathTiming]]:
    """The paths by the validator's verdict: all, accepted, rejected (empty groups left out)."""
    found = {
        "panda meshes": tally.paths,
        "panda accepted": [p for p in tally.paths if p.status is ValidationStatus.VALID],
        "panda rejected": [p for p in tally.paths if p.status is not ValidationStatus.VALID],
    }
    return {label: paths for label, paths in found.items() if paths}


def rows(tally: PandaTally) -> list[tuple[str, int, int, float, float, float, float]]:
    """Table rows (label, paths, states, naive s, plain s, numpy certified s, certified s) of
    each group."""
    return [
        (
            label,
            len(paths),
            sum(p.samples for p in paths),
            sum(p.naive for p in paths),
            sum(p.plain for p in paths),
            sum(p.numpy for p in paths),
            sum(p.certified for p in paths),
        )
        for label, paths in groups(tally).items()
    ]


def _ms_p50(paths: list[PathTiming], numpy: bool = False) -> float | None:
    if not paths:
        return None
    return round(statistics.median(p.numpy if numpy else p.certified for p in paths) * 1e3, 3)


def figures(tally: PandaTally) -> dict[str, Any]:
    """The Panda's keys of the JSON line."""
    paths = tally.paths
    states = sum(p.samples for p in paths)
    t_naive, t_pairs = sum(p.naive for p in paths), sum(p.pairs for p in paths)
    t_cert = sum(p.certified for p in paths)
    accepted = [p for p in paths if p.status is ValidationStatus.VALID]
    rejected = [p for p in paths if p.status is not ValidationStatus.VALID]
    return {
        "panda_ratio": round(t_naive / t_cert, 2),
        "panda_ratio_pairs": round(t_pairs / t_cert, 2),
        "panda_ratio_pairs_accepted": (
            round(sum(p.pairs for p in accepted) / sum(p.certified for p in accepted), 2)
            if accepted
            else None
        ),
        "panda_path_ms_p50": _ms_p50(paths),
        "panda_numpy_path_ms_p50": _ms_p50(paths, numpy=True),
        "panda_compiled_speedup": round(sum(p.numpy for p in paths) / t_cert, 2),
        "panda_numpy_only": tally.numpy_only,
        "panda_accepted_ms_p50": _ms_p50(accepted),
        "panda_rejected_ms_p50": _ms_p50(rejected),
        "panda_status_ms_p50": {
            status.value: _ms_p50([p for p in paths if p.status is status])
            for status in ValidationStatus
            if any(p.status is status for p in paths)
        },
        "panda_first_call_ms_p50": round(statistics.median(tally.first_call) * 1e3, 3),
        "panda_states_per_s": round(states / t_cert, 1),
        "panda_naive_states_per_s": round(states / t_naive, 1),
        "panda_pairs_states_per_s": round(states / t_pairs, 1),
        "panda_paths": len(paths),
        "panda_problems": tally.problems,
        "panda_verdicts": {
            kind: dict(Counter(p.status.value for p in paths if p.kind == kind)) for kind in KINDS
        },
        "panda_mismatches": tally.mismatches,
        "panda_naive_disagreements": tally.naive_disagreements,
        "panda_conservative": sum(tally.conservative.values()),
        "panda_conservative_reasons": dict(tally.conservative.most_common()),
        "panda_dense_samples": tally.dense_samples,
    }


def print_summary(panda: dict[str, Any]) -> None:
    """The verdicts, the pairs-only baseline and the conservative rejections, after the table."""
    print(
        f"panda: {panda['panda_paths']} paths in {panda['panda_problems']} problems, validator "
        f"verdicts {panda['panda_verdicts']}, mismatches {panda['panda_mismatches']}, "
        f"conservative {panda['panda_conservative']}; validator built + first path "
        f"{panda['panda_first_call_ms_p50']:.1f} ms p50; path ms p50 "
        f"{panda['panda_path_ms_p50']} (accepted {panda['panda_accepted_ms_p50']}, rejected "
        f"{panda['panda_rejected_ms_p50']}; by verdict {panda['panda_status_ms_p50']}); "
        f"numpy levels: path ms p50 {panda['panda_numpy_path_ms_p50']}, compiled "
        f"{panda['panda_compiled_speedup']}× faster; paths only the numpy levels certify: "
        f"{panda['panda_numpy_only']}"
    )
    print(
        f"panda, naive asking only the pairs it must check: {panda['panda_pairs_states_per_s']:.0f}"
        f" st/s, ratio {panda['panda_ratio_pairs']} (accepted paths "
        f"{panda['panda_ratio_pairs_accepted']}); verdicts unlike the naive loop's: "
        f"{panda['panda_naive_disagreements']}"
    )
    for reason, n in panda["panda_conservative_reasons"].items():
        print(f"  conservative: {n} × {reason}")
