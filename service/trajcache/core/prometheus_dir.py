"""The directory where several server processes share their Prometheus samples.

Kept apart from `services.bookkeeping.metrics` on purpose: it must run before any metric exists
in the process, and importing `services.bookkeeping.metrics` creates them. The command line
calls it, and the metrics read where it points, so it lives in the bottom layer both reach.
"""

from __future__ import annotations

import os
import shutil
import tempfile

MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"


def prepare_multiprocess_dir(workers: int) -> str | None:
    """Before starting `workers` server processes: a fresh PROMETHEUS_MULTIPROC_DIR, if needed.

    With several workers and no directory named, a new temporary one is named (the workers
    inherit the variable). A directory already named is emptied: samples of an earlier run
    would add up with this one's. One worker without the variable needs nothing.
    """
    path = os.environ.get(MULTIPROC_ENV)
    if workers <= 1 and not path:
        return None
    if path:
        shutil.rmtree(path, ignore_errors=True)
        os.makedirs(path, exist_ok=True)
    else:
        path = tempfile.mkdtemp(prefix="trajcache-metrics-")
        os.environ[MULTIPROC_ENV] = path
    return path
