"""Warming compiles (or loads from numba's cache) every kernel the geometry calls from Python."""

from __future__ import annotations

import json
import subprocess
import sys

# Run in a fresh interpreter: in the test session, other tests compile kernels too.
_PROBE = """
import importlib, json, pkgutil
from numba.core.registry import CPUDispatcher
import trajcache.geometry as geometry
from trajcache.geometry.warm import warm

warm()
kernels = {}
for info in pkgutil.walk_packages(geometry.__path__, "trajcache.geometry."):
    module = importlib.import_module(info.name)
    for name, value in vars(module).items():
        if isinstance(value, CPUDispatcher) and value.__module__ == info.name:
            kernels[f"{info.name}.{name}"] = value
called = {n for k in kernels.values() for n in k.py_func.__code__.co_names}
python = {"forward_kinematics_kernel", "scene_open_kernel", "self_open_kernel"}  # and kernels
entry = {
    n: len(k.signatures)
    for n, k in kernels.items()
    if n.rpartition(".")[2] not in called or n.rpartition(".")[2] in python
}
print(json.dumps(entry))
"""


def test_warm_compiles_every_kernel_called_from_python() -> None:
    """Every kernel that no other kernel calls (so Python does) has a compiled signature after
    `warm()`; kernels called from kernels are compiled into their callers."""
    run = subprocess.run(
        [sys.executable, "-c", _PROBE], capture_output=True, text=True, check=True, timeout=900
    )
    entry_points = json.loads(run.stdout.strip().splitlines()[-1])
    short = {name.rpartition(".")[2] for name in entry_points}
    assert {"forward_kinematics_kernel", "scene_open_kernel", "state_rows_kernel"} <= short
    assert {"self_open_kernel", "hull_support_climb", "sphere_state", "settle_kernel"} <= short
    cold = sorted(name for name, signatures in entry_points.items() if signatures == 0)
    assert not cold, f"kernels warm() leaves to compile on first use: {cold}"


_READ_ONLY_PROBE = """
import importlib, json, pkgutil
import numpy as np
from numba.core.registry import CPUDispatcher
import trajcache.geometry as geometry
from trajcache.cache.index import TrajectoryIndex
from trajcache.geometry.model.robot import BaseType
from trajcache.geometry.path_quality import ee_path_length
from trajcache.geometry.validation.end_clearance import SegmentClearance
from trajcache.geometry.validation.validator import TrajectoryValidator, interpolate
from trajcache.geometry.warm import warm, warm_problem

def signatures():
    counts = {}
    for info in pkgutil.walk_packages(geometry.__path__, "trajcache.geometry."):
        for name, value in vars(importlib.import_module(info.name)).items():
            if isinstance(value, CPUDispatcher):
                counts[f"{info.name}.{name}"] = len(value.signatures)
    return counts

warm()
before = signatures()
model, scene = warm_problem()
states = np.array([[-1.5, 0.0], [0.0, 0.05], [1.5, 0.1]])
states.flags.writeable = False  # as the index's cached key states are
ee_path_length(model, states)
interpolate(states[:2], model, TrajectoryValidator(model, scene).resolution)
TrajectoryValidator(model, scene).validate(states[:2])
validator = TrajectoryValidator(model, scene)
fractions, bounds = np.array([0.0, 1.0]), np.full((1, len(validator.checker.robot.radius)), 0.05)
pairs = np.full((1, len(validator.checker.robot.pair_i)), 0.05)
for array in (fractions, bounds, pairs):
    array.flags.writeable = False
SegmentClearance(fractions, bounds, pairs).unproved(validator.checker, states[:2], states[1:])
index = TrajectoryIndex(2, base=BaseType.FIXED, background_rebuild=False)
index.add(np.arange(3), states, states[::-1])
index.rebuild()  # a main block: its keys are read-only
index.add(np.array([7]), states[:1], states[2:])  # and a delta
index.query(states[0], states[2], threshold=0.3)
after = signatures()
print(json.dumps({name: [before.get(name, 0), count] for name, count in after.items()}))
"""


def test_read_only_states_compile_nothing_after_warm() -> None:
    """A request's arrays may be read-only (the index's main block, its cached key states), which
    numba types apart: the kernels they reach are warmed for them, or given a writable copy."""
    run = subprocess.run(
        [sys.executable, "-c", _READ_ONLY_PROBE],
        capture_output=True,
        text=True,
        check=True,
        timeout=900,
    )
    counts = json.loads(run.stdout.strip().splitlines()[-1])
    grown = sorted(name for name, (before, after) in counts.items() if after > before)
    assert not grown, f"compiled on use after warm(): {grown}"
