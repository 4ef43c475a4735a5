"""bench/safety_soak.py's table: the soak's figures, one measure a line."""

from __future__ import annotations

from typing import Any


def print_table(f: dict[str, Any]) -> None:
    """The figures as a two-column table."""
    rows: list[tuple[str, object]] = [
        ("warm-up calls (cleaning run S)", f["warm_calls"]),
        ("trajectories cached after warm-up", f["cached_after_warm"]),
        ("plan requests", f["plans"]),
        *((f"  {k}", v) for k, v in f["plans_by_kind"].items()),
        *((f"  options {k}", v) for k, v in f["plans_by_options"].items()),
        ("cache hits (dense-checked)", f["hits"]),
        ("planned (dense-checked)", f["planned"]),
        ("failed / no path", f["failed"]),
        ("4xx answers (start/goal in collision, …)", f["http_4xx"]),
        ("5xx answers", f["http_5xx"]),
        ("scene changes", sum(f["scene_changes"].values())),
        *((f"  {k}", v) for k, v in f["scene_changes"].items()),
        ("obstacles placed in cached paths", f["path_obstacles"]),
        ("  of them only grazing the path", f["path_obstacles_grazing"]),
        ("  blocked candidates confirmed (dense)", f["blocked_candidates_confirmed"]),
        ("  blocked candidate rejected by service", f["blocked_target_rejected"]),
        ("  answered from the cache anyway", f["blocked_hits"]),
        ("  … with the blocked trajectory itself", f["blocked_hits_target"]),
        ("  … for a grazing obstacle", f["blocked_hits_grazing"]),
        ("dense samples checked", f["dense_samples"]),
        ("collisions (dense)", f["collisions"]),
        ("out of joint limits (dense)", f["limit_violations"]),
        ("not from start to goal", f["endpoint_errors"]),
        ("UNSAFE", f["unsafe"]),
        ("trajectories cached at the end", f["cached_end"]),
        ("soak wall time s", f["soak_s"]),
        ("total wall time s", f["wall_s"]),
    ]
    print(f"{'measure':<44}{'value':>10}")
    for label, value in rows:
        print(f"{label:<44}{value!s:>10}")
    for example, count in f["http_4xx_examples"].items():
        print(f"  {count} × {example}")
    for error in f["errors"]:
        print(f"! {error}")
