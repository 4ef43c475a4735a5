"""Kernels compiled without reference counting (`_nrt=False`) never hand an array back.

Such a kernel takes no reference to the arrays it reads: its caller holds them for the call. An
array it returned would reach a caller that counts references with one reference too few, and
be freed while still in use. So every `_nrt=False` kernel that is compiled on its own (not
inlined into its caller) returns scalars, or tuples of scalars, for every signature `warm()`
compiles. numba itself refuses a new array or a view as such a kernel's result, and any
allocation in it, at compile time; an argument handed back is what it lets through.
"""

from __future__ import annotations

import json
import subprocess
import sys

# Run in a fresh interpreter, after warm(): the signatures are those a request compiles.
_PROBE = """
import importlib, json, pkgutil
import numba
from numba.core import types
from numba.core.registry import CPUDispatcher
import trajcache.geometry, trajcache.planning
from trajcache.planning.warm import warm


@numba.njit(_nrt=False)
def returns_its_argument(a):  # the finder's self-test: this one must be caught
    return a


returns_its_argument.compile("float64[:](float64[:])")


def holds_array(t):
    if isinstance(t, types.Array):
        return True
    return isinstance(t, types.BaseTuple) and any(holds_array(x) for x in t.types)


warm()
kernels = {"probe.returns_its_argument": returns_its_argument}
for package in (trajcache.geometry, trajcache.planning):
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.__module__ == info.name:
                kernels[f"{info.name}.{name}"] = value
checked, offending = [], []
for name, kernel in sorted(kernels.items()):
    options = kernel.targetoptions
    if options.get("_nrt", True) or options.get("inline") == "always":
        continue
    checked.append(name)
    if any(holds_array(o.signature.return_type) for o in kernel.overloads.values()):
        offending.append(name)
print(json.dumps({"checked": checked, "offending": offending}))
"""


def test_no_kernel_without_reference_counts_returns_an_array() -> None:
    run = subprocess.run(
        [sys.executable, "-c", _PROBE], capture_output=True, text=True, check=True, timeout=900
    )
    found = json.loads(run.stdout.strip().splitlines()[-1])
    short = {name.rpartition(".")[2] for name in found["checked"]}
    assert {"sphere_state", "forward_kinematics_kernel", "_nearest", "scene_bound"} <= short
    assert found["offending"] == ["probe.returns_its_argument"]
