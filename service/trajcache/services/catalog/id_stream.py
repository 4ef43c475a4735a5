"""How far a replica has read one id sequence (the commit log, the tombstones), and which ids
below that are still missing (`services.catalog.index_store` says why ids go missing)."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["IdStream"]

_MAX_GAPS = 100_000


@dataclass
class IdStream:
    """How far one id sequence has been read, and which ids below that are still missing."""

    hwm: int = 0
    gaps: dict[int, float] = field(default_factory=dict)  # id -> when it was first missed

    def wanted_gaps(self, now: float, ttl_s: float) -> list[int]:
        """Gaps still worth asking for."""
        expired = [i for i, t in self.gaps.items() if now - t > ttl_s]
        for i in expired:
            del self.gaps[i]
        return list(self.gaps)

    def advance(self, seen: list[int], now: float) -> None:
        """Record ids just read; ids skipped over become gaps."""
        for i in seen:
            self.gaps.pop(i, None)
        top = max(seen, default=self.hwm)
        if top > self.hwm:
            present = set(seen)
            missing = [i for i in range(self.hwm + 1, top) if i not in present]
            for i in missing[-_MAX_GAPS:]:
                self.gaps[i] = now
            self.hwm = top
