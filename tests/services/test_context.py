"""ServiceContext owns the caches of the service process and empties them on request."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trajcache.cache.memo import MemoScope
from trajcache.cache.ranking import CandidateFacts
from trajcache.core.config import Settings
from trajcache.services.context import ServiceContext


def test_clear_caches_empties_every_cache(tmp_path: Path) -> None:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'ctx.db'}", worker_backend="none")
    ctx = ServiceContext.create(settings)
    try:
        scope = MemoScope("m", "s", ())
        ctx.memo.remember(scope, np.zeros((2, 2)))
        ctx.facts.put_many({1: CandidateFacts()})
        ctx.variants.put(("m", "v"), object())  # type: ignore[arg-type]
        ctx.validators.validators.put(("m",), object())  # type: ignore[arg-type]
        assert len(ctx.memo) and len(ctx.facts) and len(ctx.variants)
        ctx.clear_caches()
        assert not ctx.memo.known_valid(scope, np.zeros((2, 2)))
        assert (len(ctx.memo), len(ctx.facts), len(ctx.variants)) == (0, 0, 0)
        assert len(ctx.validators.validators) == 0 and len(ctx.scenes) == 0
    finally:
        ctx.close()
