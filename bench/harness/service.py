"""Services for benchmarks: started by `trajcache.cli.launch`, measured here (server CPU time)."""

from __future__ import annotations

import os
from pathlib import Path

from trajcache.cli.launch import free_port, running_service, running_services, service_pid

__all__ = ["free_port", "running_service", "running_services", "server_cpu_seconds"]


def server_cpu_seconds(base: str) -> float:
    """CPU time (user + system, s) used so far by the HTTP processes of the service at `base`
    (the planner pool's processes, forked from a forkserver, are left out); Linux only (read
    from /proc), NaN elsewhere."""
    root = service_pid(base)
    proc = Path("/proc")
    if root is None or not (proc / str(root)).exists():
        return float("nan")
    tick = os.sysconf("SC_CLK_TCK")
    stats: dict[int, tuple[int, float]] = {}  # pid → (parent pid, cpu seconds)
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:  # the process ended meanwhile
            continue
        if b"forkserver" in cmdline or b"resource_tracker" in cmdline:
            continue
        stats[int(entry.name)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / tick)
    family, total, grew = {root}, 0.0, True
    while grew:
        grew = False
        for pid, (parent, _) in stats.items():
            if parent in family and pid not in family:
                family.add(pid)
                grew = True
    for pid in family:
        total += stats.get(pid, (0, 0.0))[1]
    return total
