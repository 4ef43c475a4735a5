"""How finely certified validation samples: its CPU time on the MBM Panda's paths, per spacing.

Certified validation proves the motion between consecutive samples, so where it samples decides
only its cost, never its verdict's soundness. It cuts each step of the resolution (the paper's
0.035 rad per joint) into `CERTIFY_SUBDIVISION` steps. Finer samples cost more compiled bound
evaluations but leave fewer (sample, element, object) pairs to the exact distances and the
conservative advancement run from Python; this benchmark measures the balance. A variant
`KxP` samples at K per step and cuts each segment its bound levels leave open into P pieces
before exact distances (`geometry/validation/refine.py`, `CertifierOptions.pieces`).

The MBM Panda problems (`../shared/data/mbm-panda`, --per-family of each family) are planned in
this process with the service's planning task (`mbm_inprocess`), then each solved path is
validated with validators that differ only in their variant, in turn on every path (so that
the machine's load falls alike on each):

- `whole`: the planned path, as the worker certifies it (the planner's own certification);
- `ends`: the path with start and goal moved by up to ±0.02 rad per joint (as a cache hit adapts
  it), its first and last segments only (`validate_segments`, what a same-scene hit checks).

Times are CPU time of this process (`time.process_time`), medians over the paths, after one
untimed round. The verdicts must agree across variants except where a motion passes closer
than `min_pad` (TOO_CLOSE is decided where a probe lands); disagreements are counted.

    python bench/certify_sampling.py [--per-family N] [--variants 1x1,1x3,3x1] [--smoke]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import mbm_inprocess
from mbm_problems import DEFAULT_DATA, FAMILIES, load_problems, unpacked
from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.scene.scene import Scene
from trajcache.geometry.scene.variant import model_in_scene
from trajcache.geometry.validation import validator as validation
from trajcache.geometry.validation.certify import CertifierOptions
from trajcache.geometry.warm import warm
from trajcache.planning import run
from trajcache.planning.problem import PlanningProblem

NOISE = 0.02  # rad per joint, as bench/mbm.py's replays


def _validators(
    variant: RobotModel, scene: Scene, variants: list[str]
) -> dict[str, validation.TrajectoryValidator]:
    out = {}
    for name in variants:
        k, pieces = (int(v) for v in name.split("x"))
        options = CertifierOptions(pieces=pieces)
        validator = validation.TrajectoryValidator(variant, scene, certifier=options)
        validator.subdivision = k
        out[name] = validator
    return out


def planned_cases(
    args: argparse.Namespace,
) -> list[tuple[dict[str, validation.TrajectoryValidator], np.ndarray, np.ndarray]]:
    """(validators by variant, planned path, the path with noisy ends) per solved problem."""
    source = mbm_inprocess.model_source(args)
    model = run.model_from_source(source)
    rng = np.random.default_rng(args.seed)
    cases = []
    for problem in load_problems(unpacked(args.data), list(FAMILIES), args.per_family):
        scene_source, _ = mbm_inprocess.cold_setup(model, problem)
        result = run.run_planning(
            PlanningProblem(
                source, scene_source, tuple(problem.start.tolist()), tuple(problem.goal.tolist()),
                budget_s=5.0, planner="compiled", seed=int(rng.integers(1, 2**31)),
            )
        )  # fmt: skip
        if not result.solved or result.path is None:
            continue
        scene = run.SCENES.get(scene_source.hash)
        assert scene is not None
        variant = model_in_scene(model, scene, {}, cache=run.VARIANTS)
        path = np.asarray(result.path, dtype=float)
        noisy = path.copy()
        noisy[[0, -1]] += rng.uniform(-NOISE, NOISE, (2, path.shape[1]))
        noisy[[0, -1]] = np.clip(noisy[[0, -1]], variant.lower, variant.upper)
        cases.append((_validators(variant, scene, args.variants), path, noisy))
    return cases


def _validate(
    validator: validation.TrajectoryValidator, kind: str, path: np.ndarray, noisy: np.ndarray
) -> bool:
    if kind == "whole":
        return validator.validate(path).valid
    return validator.validate_segments(noisy, [0, len(noisy) - 2]).valid


def measure(cases: list, variants: list[str]) -> tuple[dict[str, list[float]], dict[str, int]]:
    """CPU ms per (kind, variant) over the paths, and verdicts that differ between them."""
    kinds = ("whole", "ends")
    times: dict[str, list[float]] = {f"{kind} {k}": [] for kind in kinds for k in variants}
    differ = dict.fromkeys(kinds, 0)
    for timed in (False, True):
        for validators, path, noisy in cases:
            for kind in kinds:
                verdicts = set()
                for k in variants:
                    began = time.process_time()
                    verdicts.add(_validate(validators[k], kind, path, noisy))
                    if timed:
                        times[f"{kind} {k}"].append((time.process_time() - began) * 1e3)
                differ[kind] += timed and len(verdicts) > 1
    return times, differ


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--per-family", type=int, default=5)
    parser.add_argument("--variants", default="1x1,1x2,1x3,1x4,3x1")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--smoke", action="store_true", help="1 problem per family")
    args = parser.parse_args(argv)
    args.variants = args.variants.split(",")
    if args.smoke:
        args.per_family = 1
    warm()
    cases = planned_cases(args)
    times, differ = measure(cases, args.variants)
    base = args.variants[0]
    current = f"{validation.CERTIFY_SUBDIVISION}x{CertifierOptions().pieces}"
    print(f"{'paths':<10}{len(cases):>8}   (the service's variant: {current})")
    print(f"{'kind':<10}{'KxP':>5}{'CPU ms p50':>12}{'mean':>10}{'vs first':>10}")
    figures: dict[str, object] = {"paths": len(cases), "verdicts_differ": differ}
    for name, values in times.items():
        kind, k = name.split()
        p50 = statistics.median(values) if values else float("nan")
        first = statistics.median(times[f"{kind} {base}"]) if values else float("nan")
        mean = statistics.mean(values) if values else float("nan")
        print(f"{kind:<10}{k:>5}{p50:>12.3f}{mean:>10.3f}{p50 / first:>10.2f}")
        figures[f"{kind}_cpu_ms_median_{k}"] = round(p50, 3)
    print(json.dumps(figures))
    return 0 if cases else 1


if __name__ == "__main__":
    sys.exit(main())
