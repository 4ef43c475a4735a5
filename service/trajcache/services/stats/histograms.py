"""Log-spaced latency histograms: bins, a compact sparse encoding, and percentiles.

Bin 0 holds values below 1 µs (zero included); bins 1…360 split 1 µs … 1000 s into 40 bins per
decade, so a bin's upper edge is 5.9 % above its lower one; the last bin holds what is above.
A percentile is interpolated geometrically inside the bin where it falls, so it is within 5.9 %
of the exact value (`MAX_RELATIVE_ERROR`). Histograms of different hours, robots or replicas
add up bin by bin, which is what makes hourly rollups mergeable.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from trajcache.geometry.model.shapes import FloatArray

METRICS = ("lookup", "validate", "plan", "total")
LOWEST_MS = 1e-3
BINS_PER_DECADE = 40
DECADES = 9
NBINS = DECADES * BINS_PER_DECADE + 2
MAX_RELATIVE_ERROR = 10 ** (1 / BINS_PER_DECADE) - 1

IntArray = npt.NDArray[np.int64]

# One stored entry: which timing, which bin, how many values (7 bytes, little-endian, packed).
ENTRY = np.dtype([("metric", "u1"), ("bin", "<u2"), ("count", "<u4")])

_K = np.arange(NBINS, dtype=np.float64)
LOWER_EDGE = np.where(_K == 0, 0.0, LOWEST_MS * 10 ** ((_K - 1) / BINS_PER_DECADE))
UPPER_EDGE = np.where(_K == NBINS - 1, np.inf, LOWEST_MS * 10 ** (_K / BINS_PER_DECADE))


def bin_of(values_ms: npt.ArrayLike) -> IntArray:
    """The bin of each value (ms); zero, negative and NaN values land in bin 0."""
    x = np.asarray(values_ms, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.floor(np.log10(x / LOWEST_MS) * BINS_PER_DECADE) + 1
    k = np.where(np.isfinite(k) | (k > 0), k, 0.0)
    return np.clip(k, 0, NBINS - 1).astype(np.int64)


def encode(metric: npt.ArrayLike, bins: npt.ArrayLike, counts: npt.ArrayLike) -> bytes:
    """Histogram entries (which timing, which bin, how many values) as bytes."""
    metric, bins, counts = np.asarray(metric), np.asarray(bins), np.asarray(counts)
    entries = np.empty(metric.size, dtype=ENTRY)
    entries["metric"], entries["bin"], entries["count"] = metric, bins, counts
    return entries.tobytes()


def decode(blobs: Sequence[bytes]) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Entries of many encoded histograms at once: (blob index, metric, bin, count)."""
    lengths = np.array(list(map(len, blobs)), dtype=np.int64) // ENTRY.itemsize
    entries = np.frombuffer(b"".join(blobs), dtype=ENTRY)
    owner = np.repeat(np.arange(len(blobs), dtype=np.int64), lengths)
    return (
        owner,
        entries["metric"].astype(np.int64),
        entries["bin"].astype(np.int64),
        entries["count"].astype(np.int64),
    )


def percentiles(hists: npt.NDArray[np.integer], qs: Sequence[float]) -> FloatArray:
    """Percentiles (q in 0…1) of histograms (..., NBINS) → (..., len(qs)); NaN when empty."""
    counts = np.asarray(hists, dtype=np.float64)
    cum = np.cumsum(counts, axis=-1)
    total = cum[..., -1:]
    out = np.full((*counts.shape[:-1], len(qs)), np.nan)
    for i, q in enumerate(qs):
        target = np.maximum(q * total, 0.5)  # q = 0 is the smallest value's bin
        b = np.argmax(cum >= target, axis=-1)[..., None]
        before = np.take_along_axis(cum, b, -1) - np.take_along_axis(counts, b, -1)
        inside = np.maximum(np.take_along_axis(counts, b, -1), 1.0)
        frac = np.clip((target - before) / inside, 0.0, 1.0)[..., 0]
        b = b[..., 0]
        low, high = LOWER_EDGE[b], UPPER_EDGE[b]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            value = np.where(
                b == 0,
                frac * LOWEST_MS,
                np.where(np.isinf(high), low, low * (high / np.where(low > 0, low, 1)) ** frac),
            )
        out[..., i] = np.where(total[..., 0] > 0, value, np.nan)
    return out
