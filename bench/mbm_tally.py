"""What the MBM benchmark counts per family, its figures, and the table it prints.

Timings, in milliseconds, over the solved problems (a failure's time is its budget):
- `planner_ms`: the search plus the simplification (what VAMP's published figures measure):
  through the service, the answer's `timings_ms.search + simplify` (an answer without them:
  `timings_ms.plan`, the time the request waited on the planner pool); in process
  (`--in-process`), the planner's `search_ms` (OMPL: `plan_ms`) plus `simplify_ms` and
  `shortcut_ms`. In process also `worker_ms`, the planner's whole run after the per-scene setup
  (`run_ms − setup_ms` of `run_planning`: certification and repair too), and `setup_ms` apart.
- `plan_ms`: the server's `timings_ms.total` of a planned answer (adds validation and storage).
- `hit_server_ms`: the server's `timings_ms.total` of a replay answered from the cache.
- `hit_ends_proved_mean`: over those hits, the mean share of their new end segments proved from
  the clearance measured along the stored ones (`validation.ends_proved`; 0 where none was).
- `plan_phases_ms_median`, `hit_phases_ms_median`: the median of each phase of `timings_ms`
  (`validate`, `lookup`, `db`, …) over the planned answers, and over the hits.

From the answers' extras, where they carry them (else null): `compiled_share`, the share of
planned answers whose `planner` names `compiled`; `sphere_flag_rate`, the share of the states
the compiled planner checked on its sphere trees that they left to the exact check
(`sphere_open / sphere_states` of its stats; in process), else the share of planned answers
with a true `sphere_flagged`/`sphere_flags`; `repair_rate`, the share of planned answers with a
non-zero `repaired`/`repairs` (in `timings_ms` or the answer itself; in process, the stats).
`path_length` is the joint-space length of a returned path (sum of Euclidean steps, rad).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

SPHERE_KEYS = ("sphere_flagged", "sphere_flags")
REPAIR_KEYS = ("repaired", "repairs")
COMPILED = "compiled"


@dataclass
class Tally:
    """What one family's problems gave."""

    family: str
    problems: int = 0
    solved: int = 0
    clamped_goals: int = 0
    clamped_starts: int = 0
    planner_ms: list[float] = field(default_factory=list)
    plan_ms: list[float] = field(default_factory=list)
    setup_ms: list[float] = field(default_factory=list)  # in process: per-scene setup
    worker_ms: list[float] = field(default_factory=list)  # in process: the planner's whole run
    sphere_states: float = 0.0  # states the compiled planner checked on sphere trees
    sphere_open: float = 0.0  # of which the trees left to the exact check
    path_lengths: list[float] = field(default_factory=list)
    planners: Counter[str] = field(default_factory=Counter)  # planned answers by planner name
    sphere_flags: list[bool] = field(default_factory=list)
    repairs: list[bool] = field(default_factory=list)
    replays: int = 0
    hits: int = 0
    hit_server_ms: list[float] = field(default_factory=list)
    hit_validate_ms: list[float] = field(default_factory=list)  # the hits' timings_ms.validate
    hit_ends_proved: list[float] = field(default_factory=list)  # validation.ends_proved, or 0
    repaired_server_ms: list[float] = field(default_factory=list)  # replays answered "repaired"
    cross_repaired: int = 0  # --cross-scene: next-scene asks answered "repaired"
    moved_asked: int = 0  # --cross-scene: one object moved by up to 1 cm
    moved_hits: int = 0
    moved_validate_ms: list[float] = field(default_factory=list)
    moved_pairs: int = 0  # (path, object) pairs checked on hits that used a certificate
    moved_reproved: int = 0  # of which proved again
    moved_clear: int = 0  # of which clear of the certificate's swept envelope
    cross_asked: int = 0  # --cross-scene: the family's next scene, ends free there
    cross_hits: int = 0
    cross_server_ms: list[float] = field(default_factory=list)
    cross_pairs: int = 0  # (path, object) pairs checked on next-scene hits using a certificate
    cross_reproved: int = 0  # of which proved again
    cross_clear: int = 0  # of which clear of the certificate's swept envelope
    counts: Counter[str] = field(default_factory=Counter)  # paths, collisions, 4xx, …
    notes: Counter[str] = field(default_factory=Counter)  # messages, contact pairs
    phases: dict[str, list[float]] = field(default_factory=dict)  # planned answers' timings_ms
    hit_phases: dict[str, list[float]] = field(default_factory=dict)  # the hits' timings_ms

    def record_extras(self, extras: Mapping[str, Any]) -> None:
        """Note what a planned answer says of its planner, spheres and repairs."""
        self.planners[str(extras.get("planner") or "unnamed")] += 1
        self.sphere_states += float(extras.get("sphere_states", 0.0))
        self.sphere_open += float(extras.get("sphere_open", 0.0))
        for keys, seen in ((SPHERE_KEYS, self.sphere_flags), (REPAIR_KEYS, self.repairs)):
            found = [extras[k] for k in keys if k in extras]
            if found:
                seen.append(bool(found[0]))
            elif keys is REPAIR_KEYS and "repair" in extras:  # through HTTP: its time, if any
                seen.append(float(extras["repair"]) > 0.0)

    def record_phases(self, timings: Mapping[str, float], *, hit: bool = False) -> None:
        """Keep a planned answer's (or a hit's) timings, phase by phase."""
        phases = self.hit_phases if hit else self.phases
        for name, value in timings.items():
            phases.setdefault(name, []).append(float(value))


def percentile(values: list[float], q: float = 50) -> float | None:
    """The q-th percentile, rounded to 0.01 (None for no values)."""
    return round(float(np.percentile(values, q)), 2) if values else None


def _phase_medians(phases: list[dict[str, list[float]]]) -> dict[str, float | None]:
    names = sorted({name for p in phases for name in p})
    return {name: percentile([v for p in phases for v in p.get(name, [])]) for name in names}


def _mean(values: list[float]) -> float | None:
    return round(sum(values) / len(values), 4) if values else None


def _share(part: float, whole: float) -> float | None:
    return round(part / whole, 4) if whole else None


def _all(tallies: list[Tally], name: str) -> list[Any]:
    return [v for t in tallies for v in getattr(t, name)]


def _sphere_rate(tallies: list[Tally], flags: list[bool]) -> float | None:
    states = sum(t.sphere_states for t in tallies)
    if states:
        return _share(sum(t.sphere_open for t in tallies), states)
    return _share(sum(flags), len(flags))


def summary(tallies: list[Tally], in_process: bool) -> dict[str, Any]:
    """The figures over several families."""
    problems = sum(t.problems for t in tallies)
    counts = sum((t.counts for t in tallies), Counter[str]())
    planners = sum((t.planners for t in tallies), Counter[str]())
    flags, repairs = _all(tallies, "sphere_flags"), _all(tallies, "repairs")
    planner_ms = _all(tallies, "planner_ms")
    prefix = "planner_only" if in_process else "planner"
    out: dict[str, Any] = {
        "problems": problems,
        "success_rate": _share(sum(t.solved for t in tallies), problems),
        f"{prefix}_ms_median": percentile(planner_ms),
        f"{prefix}_ms_p95": percentile(planner_ms, 95),
    }
    if in_process:
        out["worker_ms_median"] = percentile(_all(tallies, "worker_ms"))
        out["setup_ms_median"] = percentile(_all(tallies, "setup_ms"))
        out["setup_ms_p95"] = percentile(_all(tallies, "setup_ms"), 95)
    else:
        out["plan_ms_median"] = percentile(_all(tallies, "plan_ms"))
        out["plan_phases_ms_median"] = _phase_medians([t.phases for t in tallies])
        out["hit_phases_ms_median"] = _phase_medians([t.hit_phases for t in tallies])
    replays = sum(t.replays for t in tallies)
    out |= {
        "compiled_share": _share(planners[COMPILED], sum(planners.values())),
        "sphere_flag_rate": _sphere_rate(tallies, flags),
        "repair_rate": _share(sum(repairs), len(repairs)),
        "path_length_median": percentile(_all(tallies, "path_lengths")),
        "collisions": counts["collisions"],
        "self_collisions": counts["self_collisions"],
        "limit_violations": counts["limit_violations"],
        "endpoint_errors": counts["endpoint_errors"],
        "paths_checked": counts["paths"],
        "clamped_goals": sum(t.clamped_goals for t in tallies),
        "clamped_starts": sum(t.clamped_starts for t in tallies),
        "http_4xx": counts["http_4xx"],
        "http_5xx": counts["http_5xx"],
        "replays": replays,
        "replay_hit_rate": _share(sum(t.hits for t in tallies), replays),
        "replay_cache_rate": _share(
            sum(t.hits + len(t.repaired_server_ms) for t in tallies), replays
        ),
        "repaired_server_ms_median": percentile(_all(tallies, "repaired_server_ms")),
        "hit_server_ms_median": percentile(_all(tallies, "hit_server_ms")),
        "hit_validate_ms_median": percentile(_all(tallies, "hit_validate_ms")),
        "hit_ends_proved_mean": _mean(_all(tallies, "hit_ends_proved")),
        "replays_skipped": counts["replays_skipped"],  # no free noisy start or goal
        "replays_planned": counts["replays_planned"],  # a success, but not from the cache
        "planners": dict(planners),
        "families": {t.family: _share(t.solved, t.problems) for t in tallies},
    }
    if any(t.moved_asked or t.cross_asked for t in tallies):
        out |= cross_summary(tallies, counts)
    return out


def cross_summary(tallies: list[Tally], counts: Counter[str]) -> dict[str, Any]:
    """The figures of `--cross-scene` (`mbm_cross.py`)."""
    total = sum  # of a field over the families
    return {
        "moved_asked": total(t.moved_asked for t in tallies),
        "moved_cache_rate": _share(
            total(t.moved_hits for t in tallies), total(t.moved_asked for t in tallies)
        ),
        "moved_validate_ms_median": percentile(_all(tallies, "moved_validate_ms")),
        "pairs_reproved_share": _share(
            total(t.moved_reproved for t in tallies), total(t.moved_pairs for t in tallies)
        ),
        "pairs_clear_share": _share(
            total(t.moved_clear for t in tallies), total(t.moved_pairs for t in tallies)
        ),
        "cross_asked": total(t.cross_asked for t in tallies),
        "cross_ends_invalid": counts["cross_ends_invalid"],
        "cross_cache_rate": _share(
            total(t.cross_hits + t.cross_repaired for t in tallies),
            total(t.cross_asked for t in tallies),
        ),
        "cross_repaired": total(t.cross_repaired for t in tallies),
        "cross_server_ms_median": percentile(_all(tallies, "cross_server_ms")),
        "cross_pairs_reproved_share": _share(
            total(t.cross_reproved for t in tallies), total(t.cross_pairs for t in tallies)
        ),
        "cross_pairs_clear_share": _share(
            total(t.cross_clear for t in tallies), total(t.cross_pairs for t in tallies)
        ),
    }


def print_table(tallies: list[Tally], in_process: bool, console: Console) -> None:
    """A row per family and one for all, then the most frequent notes."""
    table = Table(title="MotionBenchMaker, Panda" + (" (planner in process)" if in_process else ""))
    head = ["family", "problems", "solved %", "planner ms p50", "p95"]
    head += ["setup ms p50"] if in_process else ["plan ms p50", "replay hits"]
    head += ["collide", "self", "limits"]
    for name in head:
        table.add_column(name, justify="left" if name == "family" else "right")
    rows = [(t.family, [t]) for t in tallies] + [("all", tallies)]
    for name, group in rows:
        f = summary(group, in_process)
        prefix = "planner_only" if in_process else "planner"
        solved = "-" if f["success_rate"] is None else f"{100 * f['success_rate']:.1f}"
        row = [name, str(f["problems"]), solved, str(f[f"{prefix}_ms_median"]),
               str(f[f"{prefix}_ms_p95"])]  # fmt: skip
        if in_process:
            row.append(str(f["setup_ms_median"]))
        else:
            hits = sum(t.hits for t in group)
            row += [str(f["plan_ms_median"]), f"{hits}/{f['replays']}"]
        row += [str(f["collisions"]), str(f["self_collisions"]), str(f["limit_violations"])]
        table.add_row(*row, end_section=name == tallies[-1].family)
    console.print(table)
    notes = sum((Counter({f"{t.family}: {k}": n for k, n in t.notes.items()}) for t in tallies),
                Counter[str]())  # fmt: skip
    for note, n in notes.most_common(12):
        console.print(f"  {n} × {note}", markup=False, highlight=False)
