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
python = {"forward_kinematics_kernel"}  # called from Python and from kernels
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
    assert {"self_open_kernel", "hull_support_climb", "sphere_state"} <= short
    cold = sorted(name for name, signatures in entry_points.items() if signatures == 0)
    assert not cold, f"kernels warm() leaves to compile on first use: {cold}"
