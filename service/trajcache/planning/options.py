"""What every planner is told besides its problem: its budget, seed, finishing and validation."""

from __future__ import annotations

from dataclasses import dataclass

from trajcache.geometry.validation.validator import Resolution


@dataclass(frozen=True)
class SearchOptions:
    """A planner's budget (seconds of wall time) and seed; how long it may shortcut a found
    path; and the validator its answers pass (`resolution`, `certified`), whose resolution its
    motion checks sample at too."""

    budget_s: float
    seed: int
    shortcut_s: float = 0.25
    resolution: Resolution | None = None
    certified: bool = True
