"""The paper's Tables 1 and 2 (REFERENCE.md protocol) through the real HTTP service.

Every row is one cleaning run played by a robot through the REST API of `trajcache serve`
(uvicorn on loopback; a temporary SQLite database each, or a fresh schema each on the PostgreSQL
server given with --postgres). The robot keeps its scene current as the run changes it (PUT, then
PATCH when a door opens or a seat goes up or down) and asks for a plan for every call.

Rows, each cache its own service:
- Table 1 (simulation, seed S): no cache (every call planned); run 1 (seed S) with an empty
  cache; run 2 (seed S+1: other noise and door angles) with the cache of run 1.
- Table 2: pre-seeding, door-sweep runs with every door at 0°, 10°, …, 90° played by a simulated
  robot into one cache; the "real robot" on the perturbed restroom (objects shifted, door angles
  between the seeded ones, larger noise; seed S+2): (a) no cache, (b) empty cache, (c) the
  pre-seeded cache, (d) a second run (seed S+3) on top of (c).
- Beyond the paper: run 1 and 2, and the real robot's (b), again with `options.match = "arm"`
  (a request whose base does not move matches on the arm joints alone, so a motion learned at one
  stall serves the same motion at the next).

Every trajectory returned in every row is checked by an independent dense check
(harness.dense: plain FCL, steps 4× finer than the paper's, no padding) in the scene
in force at its call;
`collisions` counts the ones it finds in collision. Time columns: see harness.tables.

No cache: calls carry `options.lookup = false`; a service without that option gets a threshold
of 1e-12 instead, which no two different states fall within. The no-cache service is emptied
after every row, so nothing it planned serves a later row's identical calls.

Paired baseline (unless --unpaired): each call of a cached row is also sent, right next to it, to
the no-cache service by a robot of its own in the same scene. The row's "paired ×" divides that
time by the row's, so both sides of the ratio ran under the same load. These paired answers are
only timed; they are planner answers like those of the no-cache rows, which are checked.

Prints the tables with the paper's figures under ours, writes all rows as JSON and a PNG chart,
and ends with one JSON line.

    python bench/paper_tables.py [--smoke] [--seed S] [--postgres URL] [--calls N]
                                 [--rows KEYS] [--unpaired] [--json PATH] [--chart PATH]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from harness.caches import Cache, caches, empty_cache, no_cache_options
from harness.dense import DenseChecker, reference_checker
from harness.replay import CallRecord, RobotClient, cached_count
from harness.tables import (
    PAPER_MEAN_FALLBACK_MS,
    PAPER_MEAN_HIT_MS,
    Row,
    draw_chart,
    format_costs,
    format_misses,
    format_table,
    headline,
    row_json,
)
from trajcache.geometry.scene.payload import scene_to_payload
from trajcache.reference.cleaning import CleaningRun, cleaning_run, door_sweep_run

FULL: dict[str, Any] = {"fallback": True, "match": "full"}
ARM: dict[str, Any] = {"fallback": True, "match": "arm"}
SWEEP_DEG = tuple(range(0, 91, 10))
CACHES = ("none", "sim", "sim_arm", "seeded", "real", "real_arm")
NOTE = """\
Rows marked + are beyond the paper. Times are sums over the row's calls of the service's own
timings_ms (lookup+val = lookup + validate; total adds the database); wall is the client-side
request time. speed-up = the no-cache row's total / the row's total (the paper's definition);
paired × = the same calls planned without a cache, each right next to the row's call, / the
row's total: both sides see the same load on a shared machine."""
ARTIFACTS = Path("artifacts")


@dataclass(frozen=True)
class RowSpec:
    """What one row plays: a run, against which cache; rows named real_* are the real robot."""

    key: str
    table: int
    label: str
    cache: str
    run: Callable[[], CleaningRun]

    @property
    def kind(self) -> str:
        """The robot's kind at the service."""
        return "real" if self.key.startswith("real") else "sim"

    @property
    def options(self) -> str:
        """Plan options: "none" (every call planned), "arm" or "full" matching."""
        return "none" if self.cache == "none" else "arm" if self.key.endswith("_arm") else "full"

    @property
    def baseline(self) -> str:
        """The no-cache row the speed-up is measured against (as in the paper)."""
        return f"{self.kind}_none"


def row_specs(seed: int, sweep: tuple[int, ...]) -> list[RowSpec]:
    """The rows in the order they are run."""

    def run1() -> CleaningRun:
        return cleaning_run(seed)

    def run2() -> CleaningRun:
        return cleaning_run(seed + 1)

    def real() -> CleaningRun:
        return cleaning_run(seed + 2, perturbed=True)

    def real2() -> CleaningRun:
        return cleaning_run(seed + 3, perturbed=True)

    def swept(deg: int) -> Callable[[], CleaningRun]:
        return lambda: door_sweep_run(float(deg), seed)

    return [
        RowSpec("sim_none", 1, "no cache", "none", run1),
        RowSpec("run1", 1, "run 1, empty cache", "sim", run1),
        RowSpec("run2", 1, "run 2, cache of run 1", "sim", run2),
        RowSpec("run1_arm", 1, "+ run 1, empty cache, match=arm", "sim_arm", run1),
        RowSpec("run2_arm", 1, "+ run 2, cache of run 1, match=arm", "sim_arm", run2),
        *(RowSpec(f"sweep_{d}", 2, f"simulation, doors {d}°", "seeded", swept(d)) for d in sweep),
        RowSpec("real_none", 2, "real (a), no cache", "none", real),
        RowSpec("real_empty", 2, "real (b), empty cache", "real", real),
        RowSpec("real_empty_arm", 2, "+ real (b), empty cache, match=arm", "real_arm", real),
        RowSpec("real_seeded", 2, "real (c), pre-seeded cache", "seeded", real),
        RowSpec("real_second", 2, "real (d), second run on (c)", "seeded", real2),
    ]


def dense_check(checker: DenseChecker, run: CleaningRun, row: Row) -> None:
    """Check every trajectory of the row densely in the scene in force at its call."""
    payloads: dict[str, dict[str, Any]] = {}
    contacts: set[str] = set()
    for record, call in zip(row.records, run.calls, strict=False):
        scene = run.scene_for(call)
        if record.scene_hash != scene.hash:
            raise RuntimeError(f"call {call.index} was planned in another scene")
        if record.states is None:
            continue
        if scene.hash not in payloads:
            payloads[scene.hash] = scene_to_payload(scene)
        verdict = checker.check(record.states, scene.hash, payloads[scene.hash])
        row.dense_samples += verdict.samples
        row.collisions += verdict.collides
        row.limit_violations += verdict.limit_samples > 0
        row.endpoint_errors += not _joins(record)
        contacts.update(f"{a}–{b}" for a, b in verdict.contacts)
    row.contacts = sorted(contacts)


def _joins(record: CallRecord) -> bool:
    """Whether the trajectory starts at the request's start and ends at its goal (θ mod 2π)."""
    assert record.states is not None
    for state, want in ((record.states[0], record.start), (record.states[-1], record.goal)):
        diff = state - want
        diff[2] = (diff[2] + np.pi) % (2 * np.pi) - np.pi
        if np.max(np.abs(diff)) > 1e-6:
            return False
    return True


def play_rows(
    specs: list[RowSpec],
    services: dict[str, Cache],
    calls: int | None,
    no_cache: dict[str, Any] | None,
    on_row: Callable[[RowSpec, Row, float], None] | None = None,
    *,
    paired: bool = True,
) -> dict[str, Row]:
    """Play every row in order, each followed by its dense check (outside the timed calls).

    `no_cache` are the options that make the no-cache service plan every call. When `paired`,
    every call of a cached row is also planned without a cache, right next to it, by a robot of
    the no-cache service: the row's paired baseline.
    """
    checker = reference_checker()
    options = {"full": FULL, "arm": ARM, "none": no_cache or {}}
    rows: dict[str, Row] = {}
    for spec in specs:
        cache = services[spec.cache]
        run = spec.run()
        name = spec.key.replace("_", "-")
        robot = RobotClient(cache.client, name, cache.model_id, spec.kind)
        shadow = None
        if paired and no_cache is not None and spec.options != "none":
            none = services["none"]
            shadow = RobotClient(none.client, f"{name}-paired", none.model_id, spec.kind)
        began = time.perf_counter()
        records, baseline = play_paired(robot, shadow, run, options[spec.options], no_cache, calls)
        elapsed = time.perf_counter() - began
        cached = None if spec.options == "none" else cached_count(cache.client, cache.model_id)
        uncached = records if spec.options == "none" else baseline or []
        if any(r.hit for r in uncached):
            raise RuntimeError(f"{spec.key}: the no-cache service answered from its cache")
        if "none" in services:  # nothing it planned may serve a later row's identical calls
            empty_cache(services["none"].client, services["none"].model_id)
        row = Row(spec.key, spec.table, spec.label, spec.baseline, records, cached, baseline)
        dense_check(checker, run, row)
        rows[spec.key] = row
        if on_row is not None:
            on_row(spec, row, elapsed)
        else:
            f = row.figures()
            print(
                f"  {spec.label}: {f['hits']}/{f['calls']} hits, {f['planner_calls']} planned, "
                f"{f['collisions']} collisions, {elapsed:.1f} s",
                file=sys.stderr,
            )
    return rows


def play_paired(
    robot: RobotClient,
    shadow: RobotClient | None,
    run: CleaningRun,
    options: dict[str, Any],
    no_cache: dict[str, Any] | None,
    calls: int | None,
) -> tuple[list[CallRecord], list[CallRecord] | None]:
    """Play the run; with a shadow robot, each call is planned without a cache next to it."""
    if shadow is None or no_cache is None:
        return robot.play(run, options, calls), None
    records, paired = [], []
    for k, call in enumerate(run.calls[:calls]):
        if k % 2:  # alternate which goes first
            records.append(robot.call(run, call, options))
            paired.append(shadow.call(run, call, no_cache))
        else:
            paired.append(shadow.call(run, call, no_cache))
            records.append(robot.call(run, call, options))
    return records, paired


@dataclass(frozen=True)
class Protocol:
    """What to play: the workload seed, calls per run, door sweep, rows, database, pairing."""

    seed: int = 1
    calls: int | None = None  # None: every call of each run
    sweep: tuple[int, ...] = SWEEP_DEG
    rows: frozenset[str] | None = None  # None: every row
    postgres: str | None = None  # None: a temporary SQLite database per service
    paired: bool = True
    smoke: bool = False

    def specs(self) -> list[RowSpec]:
        """The rows to play, in order; unknown row keys are a ValueError."""
        specs = row_specs(self.seed, self.sweep)
        if self.rows is None:
            return specs
        unknown = self.rows - {s.key for s in specs}
        if unknown:
            raise ValueError(f"unknown rows: {', '.join(sorted(unknown))}")
        return [s for s in specs if s.key in self.rows]

    def config(self) -> dict[str, Any]:
        """The protocol as recorded in the JSON document."""
        db = "postgresql" if self.postgres else "sqlite"
        return {"seed": self.seed, "calls_per_run": self.calls, "sweep_deg": list(self.sweep)} | {
            "database": db,
            "smoke": self.smoke,
        }


def run_protocol(
    protocol: Protocol, on_row: Callable[[RowSpec, Row, float], None] | None = None
) -> tuple[dict[str, Row], dict[str, Any]]:
    """Start the services, play the rows (calling `on_row` after each); the rows and config."""
    specs = protocol.specs()
    needed = tuple(
        name
        for name in CACHES
        if any(s.cache == name for s in specs) or (name == "none" and protocol.paired)
    )
    began = time.perf_counter()
    with caches(protocol.postgres, needed) as services:
        no_cache: dict[str, Any] | None = None
        mode = "-"
        if "none" in services:
            no_cache, mode = no_cache_options(services["none"].client, services["none"].model_id)
        print(f"services ready in {time.perf_counter() - began:.1f} s", file=sys.stderr)
        rows = play_rows(specs, services, protocol.calls, no_cache, on_row, paired=protocol.paired)
    return rows, protocol.config() | {"no_cache": mode}


def parse_args(argv: list[str] | None = None, artifacts: Path = ARTIFACTS) -> argparse.Namespace:
    """Command-line options; JSON and chart go to `artifacts` unless given."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--smoke", action="store_true", help="24 calls per run, doors 0° and 90°")
    parser.add_argument("--seed", type=int, default=1, help="workload seed S (run 1)")
    parser.add_argument("--postgres", metavar="URL", help="PostgreSQL server (default: SQLite)")
    parser.add_argument("--calls", type=int, help="play only the first N calls of each run")
    parser.add_argument(
        "--rows",
        help="play only these rows (comma-separated keys, e.g. sim_none,run1,run2); a row that "
        "builds on another's cache then finds less in it",
    )
    parser.add_argument(
        "--unpaired",
        action="store_true",
        help="skip the paired baseline (each call of a cached row also planned without a cache)",
    )
    parser.add_argument("--json", type=Path, default=artifacts / "paper_tables.json")
    parser.add_argument("--chart", type=Path, default=artifacts / "paper_tables.png")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None, artifacts: Path = ARTIFACTS) -> None:
    """Run the protocol; print the tables and the JSON line; write the JSON file and chart."""
    args = parse_args(argv, artifacts)
    protocol = Protocol(
        seed=args.seed,
        calls=args.calls or (24 if args.smoke else None),
        sweep=(0, 90) if args.smoke else SWEEP_DEG,
        rows=frozenset(args.rows.split(",")) if args.rows else None,
        postgres=args.postgres,
        paired=not args.unpaired,
        smoke=args.smoke,
    )
    try:
        protocol.specs()
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    rows, config = run_protocol(protocol)
    report(rows, config, args.json, args.chart)


def report(
    rows: dict[str, Row], config: dict[str, Any], json_path: Path | None, chart: Path | None
) -> dict[str, Any]:
    """Print the tables and the JSON line; write the JSON document and the chart (each unless
    None); return the summary."""
    scope = f"{config['calls_per_run'] or 'all'} calls per run, seed {config['seed']}"
    scope += f", {config['database']}"
    print(format_table(f"Table 1: simulation ({scope})", 1, rows))
    print()
    print(format_table(f"Table 2: pre-seeding and the real robot ({scope})", 2, rows))
    print()
    print(NOTE)
    extra = {k: config[k] for k in ("no_cache", "database", "smoke")}
    summary = headline(rows, extra)
    print(
        f"Mean fallback planning per planner call: {summary['mean_fallback_ms']} ms "
        f"(paper ≈ {PAPER_MEAN_FALLBACK_MS:g}); mean lookup+validation per hit: "
        f"{summary['mean_hit_ms']} ms (paper ≈ {PAPER_MEAN_HIT_MS:g})."
    )
    print(format_costs(rows, "run2", "sim_none"))
    print(format_misses(rows, ("run1", "run2", "real_empty", "real_seeded", "real_second")))
    document = {
        "config": config,
        "rows": [row_json(row, rows) for row in rows.values()],
        "summary": summary,
    }
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(document, indent=1))
        print(f"wrote {json_path}", file=sys.stderr)
    if chart is not None:
        draw_chart(rows, chart, f"Service time per run ({scope})")
        print(f"wrote {chart}", file=sys.stderr)
    print(json.dumps(summary))
    return summary
