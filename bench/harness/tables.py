"""Rows of the paper's Tables 1 and 2: our figures, the paper's, the printed tables and the chart.

Time columns come from the service's own `timings_ms`, summed over a row's calls: lookup +
validation (`lookup` + `validate`, which includes validating a freshly planned path), planner
(`plan`: the fallback planner in the worker pool), and the service total (`total`: those plus
the database). "wall" is the client-side time of the requests (HTTP and serialization included).
Speed-ups divide the no-cache row's time by the row's: simulation rows (Table 1 and the door
sweep) against Table 1's no-cache row, real-robot rows against Table 2's, as in the paper. The
paired speed-up divides instead the time of the same calls planned without a cache, each sent
right next to the row's call, so that load from other processes hits both sides alike.
"""

from __future__ import annotations

import statistics
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from harness.replay import CallRecord


@dataclass(frozen=True)
class PaperRow:
    """A row of the paper's tables (None where the paper has no figure)."""

    calls: int
    hits: int | None
    planned: int
    cached: int | None
    lookup_s: float | None
    plan_s: float
    total_s: float
    speedup: float


# Yakovyna & Medvid 2025, Tables 1 and 2.
PAPER: dict[str, PaperRow] = {
    "sim_none": PaperRow(271, None, 271, None, None, 18.319, 18.319, 1.0),
    "run1": PaperRow(271, 137, 134, 134, 0.698, 14.319, 15.619, 1.10),
    "run2": PaperRow(272, 253, 19, 143, 2.233, 3.301, 5.534, 3.31),
    "sweep_0": PaperRow(271, 137, 134, 134, 0.751, 14.031, 14.782, 1.24),
    "sweep_10": PaperRow(272, 228, 44, 178, 2.208, 6.246, 8.454, 2.17),
    "sweep_20": PaperRow(272, 238, 34, 212, 2.510, 5.674, 8.184, 2.24),
    "sweep_30": PaperRow(273, 249, 24, 236, 2.615, 3.891, 6.506, 2.82),
    "sweep_40": PaperRow(273, 255, 18, 254, 2.707, 2.950, 5.657, 3.24),
    "sweep_50": PaperRow(272, 257, 15, 269, 2.918, 2.718, 5.636, 3.25),
    "sweep_60": PaperRow(274, 262, 12, 281, 3.001, 2.225, 5.226, 3.51),
    "sweep_70": PaperRow(274, 264, 10, 291, 3.012, 1.786, 4.798, 3.82),
    "sweep_80": PaperRow(278, 268, 10, 301, 3.098, 1.802, 4.900, 3.74),
    "sweep_90": PaperRow(264, 262, 2, 303, 2.997, 0.545, 3.542, 5.17),
    "real_none": PaperRow(278, None, 278, None, None, 27.396, 27.396, 1.0),
    "real_empty": PaperRow(279, 138, 141, 141, 1.020, 19.875, 20.895, 1.31),
    "real_seeded": PaperRow(277, 261, 16, 319, 4.115, 3.581, 7.696, 3.56),
    "real_second": PaperRow(278, 269, 9, 328, 4.202, 2.090, 6.292, 4.35),
}
PAPER_MEAN_FALLBACK_MS = 68.0
PAPER_MEAN_HIT_MS = 9.0


@dataclass
class Row:
    """One row of our tables: the calls of one run against one cache, and what they got."""

    key: str
    table: int
    label: str
    baseline: str  # key of the no-cache row its speed-up is measured against
    records: list[CallRecord]
    cached_after: int | None  # None: a no-cache row
    paired: list[CallRecord] | None = None  # the same calls planned without a cache, alongside
    collisions: int = 0  # trajectories the dense check finds in collision
    limit_violations: int = 0  # trajectories with a sample outside the joint limits
    endpoint_errors: int = 0  # trajectories that do not join the request's start and goal
    dense_samples: int = 0
    contacts: list[str] = field(default_factory=list)

    def _sum(self, *keys: str) -> float:
        return sum(r.timings[k] for r in self.records for k in keys) / 1e3

    def figures(self) -> dict[str, Any]:
        """The row's counts and times (seconds)."""
        hits = [r for r in self.records if r.hit]
        planned = [r for r in self.records if r.planned]
        return {
            "calls": len(self.records),
            "hits": len(hits),
            "hit_rate": len(hits) / max(len(self.records), 1),
            "planner_calls": len(planned),
            "failed": sum(r.status != "success" for r in self.records),
            "cached_after": self.cached_after,
            "lookup_validate_s": self._sum("lookup", "validate"),
            "plan_s": self._sum("plan"),
            "db_s": self._sum("db"),
            "total_s": self._sum("total"),
            "wall_s": sum(r.wall_ms for r in self.records) / 1e3,
            "mean_hit_ms": _mean([r.timings["lookup"] + r.timings["validate"] for r in hits]),
            "mean_fallback_ms": _mean([r.timings["plan"] for r in planned]),
            "per_hit_ms": _means(hits),
            "per_planned_ms": _means(planned),
            "collisions": self.collisions,
            "limit_violations": self.limit_violations,
            "endpoint_errors": self.endpoint_errors,
            "dense_samples": self.dense_samples,
        }

    def misses(self) -> dict[str, Any]:
        """Why the calls the cache did not serve missed, and which calls they were."""
        missed = [r for r in self.records if not r.hit]
        causes: Counter[str] = Counter()
        for r in missed:
            if r.candidates_tried == 0:
                causes["no cached start/goal within the threshold"] += 1
            else:
                statuses = sorted({str(x["status"]) for x in r.rejected}) or ["rejected"]
                causes["every candidate rejected (" + ", ".join(statuses) + ")"] += 1
        labels = Counter(r.label for r in missed)
        return {"count": len(missed), "causes": dict(causes), "labels": dict(labels.most_common())}


def _mean(values: list[float]) -> float | None:
    return statistics.fmean(values) if values else None


def _means(records: list[CallRecord]) -> dict[str, float | None]:
    """Mean service timings and client wall time (ms) of some calls."""
    keys = ("lookup", "validate", "plan", "db", "total")
    out = {k: _mean([r.timings[k] for r in records]) for k in keys}
    out["wall"] = _mean([r.wall_ms for r in records])
    return out


def row_json(row: Row, rows: dict[str, Row]) -> dict[str, Any]:
    """The row as JSON: figures, speed-ups, misses and the paper's figures."""
    out: dict[str, Any] = {"key": row.key, "table": row.table, "label": row.label}
    out.update(row.figures())
    out.update(speedups(row, rows))
    if row.paired:
        out["paired_total_s"] = sum(r.timings["total"] for r in row.paired) / 1e3
        out["paired_wall_s"] = sum(r.wall_ms for r in row.paired) / 1e3
    out["misses"] = row.misses()
    out["contacts"] = row.contacts
    out["calls_detail"] = [r.summary() for r in row.records]
    paper = PAPER.get(row.key)
    out["paper"] = None if paper is None else paper.__dict__
    return out


def speedups(row: Row, rows: dict[str, Row]) -> dict[str, float | None]:
    """Speed-ups against the row's no-cache row (service total, wall) and its paired baseline."""
    ours = row.figures()
    out: dict[str, float | None] = dict.fromkeys(
        ("speedup", "wall_speedup", "paired_speedup", "paired_wall_speedup")
    )
    base = rows.get(row.baseline)
    if base is not None and ours["total_s"] and ours["wall_s"]:
        out["speedup"] = base.figures()["total_s"] / ours["total_s"]
        out["wall_speedup"] = base.figures()["wall_s"] / ours["wall_s"]
    if row.paired and ours["total_s"] and ours["wall_s"]:
        out["paired_speedup"] = sum(r.timings["total"] for r in row.paired) / 1e3 / ours["total_s"]
        out["paired_wall_speedup"] = sum(r.wall_ms for r in row.paired) / 1e3 / ours["wall_s"]
    return out


def headline(rows: dict[str, Row], extra: dict[str, Any]) -> dict[str, Any]:
    """The final JSON line."""

    def fig(key: str, name: str) -> Any:
        if key not in rows:
            return None
        value = {**rows[key].figures(), **speedups(rows[key], rows)}[name]
        return round(value, 4) if isinstance(value, float) else value

    every = [r for row in rows.values() for r in row.records]
    hits = [r.timings["lookup"] + r.timings["validate"] for r in every if r.hit]
    planned = [r.timings["plan"] for r in every if r.planned]
    out = {
        "run2_hit_rate": fig("run2", "hit_rate"),
        "run2_speedup": fig("run2", "speedup"),
        "real_seeded_hit_rate": fig("real_seeded", "hit_rate"),
        "real_seeded_speedup": fig("real_seeded", "speedup"),
        "collisions": sum(row.collisions for row in rows.values()),
        "run1_hit_rate": fig("run1", "hit_rate"),
        "run2_wall_speedup": fig("run2", "wall_speedup"),
        "run2_paired_speedup": fig("run2", "paired_speedup"),
        "real_seeded_paired_speedup": fig("real_seeded", "paired_speedup"),
        "real_seeded_wall_speedup": fig("real_seeded", "wall_speedup"),
        "real_second_hit_rate": fig("real_second", "hit_rate"),
        "real_second_speedup": fig("real_second", "speedup"),
        "sweep_90_hit_rate": fig("sweep_90", "hit_rate"),
        "sweep_90_speedup": fig("sweep_90", "speedup"),
        "run1_arm_hit_rate": fig("run1_arm", "hit_rate"),
        "run2_arm_hit_rate": fig("run2_arm", "hit_rate"),
        "real_empty_hit_rate": fig("real_empty", "hit_rate"),
        "real_empty_arm_hit_rate": fig("real_empty_arm", "hit_rate"),
        "arm_collisions": sum(r.collisions for k, r in rows.items() if k.endswith("_arm")),
        "mean_hit_ms": round(float(np.mean(hits)), 3) if hits else None,
        "mean_fallback_ms": round(float(np.mean(planned)), 3) if planned else None,
        "failed_calls": sum(r.status != "success" for r in every),
        "trajectories_checked": sum(r.states is not None for r in every),
        "dense_samples": sum(row.dense_samples for row in rows.values()),
        "limit_violations": sum(row.limit_violations for row in rows.values()),
        "endpoint_errors": sum(row.endpoint_errors for row in rows.values()),
    }
    out.update(extra)
    return out


_COLUMNS = (
    ("calls", 6), ("hits", 6), ("hit %", 7), ("planner", 8), ("failed", 7), ("cached", 7),
    ("lookup+val s", 13), ("planner s", 10), ("db s", 7), ("total s", 8), ("wall s", 8),
    ("speed-up", 9), ("wall ×", 7), ("paired ×", 9), ("collisions", 11),
)  # fmt: skip
_LABEL = 38


def _cell(value: Any, fmt: str = "") -> str:
    if value is None:
        return "-"
    return format(value, fmt) if fmt else str(value)


def _our_cells(row: Row, rows: dict[str, Row]) -> list[str]:
    f, s = row.figures(), speedups(row, rows)
    return [
        _cell(f["calls"]), _cell(f["hits"]), _cell(100 * f["hit_rate"], ".1f"),
        _cell(f["planner_calls"]), _cell(f["failed"]), _cell(f["cached_after"]),
        _cell(f["lookup_validate_s"], ".3f"), _cell(f["plan_s"], ".3f"), _cell(f["db_s"], ".3f"),
        _cell(f["total_s"], ".3f"), _cell(f["wall_s"], ".3f"),
        _cell(s["speedup"], ".2f") + ("×" if s["speedup"] else ""),
        _cell(s["wall_speedup"], ".2f"), _cell(s["paired_speedup"], ".2f"),
        _cell(f["collisions"]),
    ]  # fmt: skip


def _paper_cells(p: PaperRow) -> list[str]:
    rate = None if p.hits is None else 100 * p.hits / p.calls
    return [
        _cell(p.calls), _cell(p.hits), _cell(rate, ".1f"), _cell(p.planned), "-",
        _cell(p.cached), _cell(p.lookup_s, ".3f"), _cell(p.plan_s, ".3f"), "-",
        _cell(p.total_s, ".3f"), "-", f"{p.speedup:.2f}×", "-", "-", "-",
    ]  # fmt: skip


def _line(label: str, cells: list[str]) -> str:
    body = "".join(c.rjust(w) for c, (_, w) in zip(cells, _COLUMNS, strict=True))
    return f"{label[:_LABEL]:<{_LABEL}}{body}"


def format_table(title: str, table: int, rows: dict[str, Row]) -> str:
    """One table: our row, then the paper's figures for it where the paper has them."""
    header = _line("row", [name for name, _ in _COLUMNS])
    lines = [title, header, "-" * len(header)]
    for row in rows.values():
        if row.table != table:
            continue
        lines.append(_line(row.label, _our_cells(row, rows)))
        if row.key in PAPER:
            lines.append(_line("    paper", _paper_cells(PAPER[row.key])))
    return "\n".join(lines)


def format_misses(rows: dict[str, Row], keys: tuple[str, ...]) -> str:
    """Why the headline rows' calls missed the cache."""
    lines = ["Calls the cache did not serve:"]
    for key in keys:
        if key not in rows:
            continue
        m = rows[key].misses()
        causes = "; ".join(f"{n} {cause}" for cause, n in m["causes"].items()) or "none"
        top = ", ".join(f"{label} ×{n}" for label, n in list(m["labels"].items())[:4])
        lines.append(f"  {rows[key].label}: {m['count']} ({causes})" + (f"; {top}" if top else ""))
    return "\n".join(lines)


def format_costs(rows: dict[str, Row], hit_key: str, planned_key: str) -> str:
    """Mean cost of a cache hit and of a planned call: what bounds the speed-up."""
    lines = []
    for key, what, name in (
        (hit_key, "per_hit_ms", "hit"),
        (planned_key, "per_planned_ms", "planned call"),
    ):
        if key not in rows:
            continue
        m = rows[key].figures()[what]
        if m["total"] is None:
            continue
        parts = ", ".join(f"{k} {m[k]:.2f}" for k in ("lookup", "validate", "plan", "db"))
        lines.append(
            f"Mean {name} ({rows[key].label}): {parts}; service total {m['total']:.2f} ms, "
            f"client wall {m['wall']:.2f} ms"
        )
    return "\n".join(lines)


def draw_chart(rows: dict[str, Row], path: Path, title: str) -> None:
    """Horizontal bars: each row's service time split into lookup+validation, planning, other."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ordered = list(rows.values())[::-1]
    figures = [r.figures() for r in ordered]
    lookup = [f["lookup_validate_s"] for f in figures]
    plan = [f["plan_s"] for f in figures]
    other = [max(f["total_s"] - a - b, 0.0) for f, a, b in zip(figures, lookup, plan, strict=True)]
    pairs = zip(ordered, figures, strict=True)
    labels = [f"{r.label}  ({100 * f['hit_rate']:.1f}% hits)" for r, f in pairs]
    fig, ax = plt.subplots(figsize=(11, 0.42 * len(ordered) + 1.6))
    y = range(len(ordered))
    ax.barh(y, lookup, color="#2b8cbe", label="lookup + validation")
    ax.barh(y, plan, left=lookup, color="#e34a33", label="fallback planning")
    left = [a + b for a, b in zip(lookup, plan, strict=True)]
    ax.barh(y, other, left=left, color="#bdbdbd", label="database and bookkeeping")
    ax.set_yticks(list(y), labels, fontsize=8)
    ax.set_xlabel("service time per run (s, sum of timings_ms)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
