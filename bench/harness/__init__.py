"""The benchmark harness: the paper's protocol through the real service, and what it measures with.

- `paper`: the paper's Tables 1 and 2 (`bench/paper_tables.py`); `tables`: their rows, the
  printed tables and the chart (matplotlib, a development extra).
- `caches`: warmed-up services side by side, one per cache; `replay`: a robot playing cleaning
  runs through the REST API; `dense`: the independent dense check of returned trajectories.
- `mbm_panda`: the MotionBenchMaker Panda registered as shipped, for every MBM benchmark.
- `service`: the server processes' CPU time, over `trajcache.cli.launch` (the one way a
  service is started for measurement, shared with `trajcache demo`).

The bench scripts import it as `harness` (they run from `bench/`); `tests/bench/conftest.py`
puts `bench/` on the path for their tests.
"""
