"""What the benchmarks print: percentiles and the two-column table of measures."""

from __future__ import annotations

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
