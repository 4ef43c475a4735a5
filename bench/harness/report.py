"""What the benchmarks print: percentiles, the two-column table of measures, and the JSON line
with the independent checks' counts."""

from __future__ import annotations

import json
import time
from collections import Counter
from typing import Any

import numpy as np


def pct(values: list[float], q: float) -> float:
    """The q-th percentile (0-100); NaN when there are none."""
    return float(np.percentile(values, q)) if values else float("nan")


def print_measures(rows: list[tuple[str, object]], label_width: int, value_width: int) -> None:
    """Print `rows` under a "measure / value" header, floats with three decimals."""
    print(f"{'measure':<{label_width}}{'value':>{value_width}}")
    for label, value in rows:
        text = f"{value:.3f}" if isinstance(value, float) else str(value)
        print(f"{label:<{label_width}}{text:>{value_width}}")


def print_checked(
    figures: dict[str, Any], counts: Counter[str], *, check: str, began: float, smoke: bool
) -> int:
    """Print `figures` as the JSON line, followed by the independent checks' counts (`check`:
    the benchmark's own, then collisions) and the HTTP errors; the exit status: 1 when a check
    failed or the service answered a 5xx."""
    checked = (check, "collisions", "self_collisions", "http_4xx", "http_5xx")
    figures = {**figures, **{name: counts[name] for name in checked}}
    figures |= {"wall_s": round(time.perf_counter() - began, 1), "smoke": smoke}
    print(json.dumps(figures))
    bad = figures[check] or figures["collisions"] or figures["self_collisions"]
    return 1 if bad or figures["http_5xx"] else 0
