"""What happens after an answer: its record, why candidates were rejected, its quality, refusals
and the metrics, in one package.

An answer is built by its concept (`services.plan.answers`, `services.cartesian.path`); from
then on everything is here:

- `outcomes`: `record_outcome`, the one step every plan answer takes (`PlanOutcome`): its record
  queued, the ranking facts of a hit updated, the answer counted in the metrics; and
  `Requester`, who asked;
- `rejections`: the one list of a request's rejected candidates (`Rejections`), and the event
  entries that say where each failed;
- `answer_quality`: the quality and timing a request asks to have with its answer, computed
  from the settings and validators it is handed;
- `refusals`: the plan event and count of a request refused before an answer;
- `metrics`: every Prometheus metric, the planner pool's sampler and the cache-size collector;
- `records`, `record_batch`: the ordered writer of usage counters, plan events, new
  trajectories' quality columns and certificates, off the request's thread;
- `ranking_facts`: ranking facts kept in memory briefly, kept current by every outcome.

A stored trajectory's quality, and the timing it shares with answers (`services.quality`), is
not here: the catalog computes it when it stores a trajectory, and the catalog lies below the
bookkeeping (the writer writes certificates through it), so it stays in the bottom layer of the
services, which both reach.

Below the plan flow and the service context, which holds the writer and the facts: a concept
records through it without knowing the flow, and nothing here knows the context or a concept
above it (each function is handed the writer, the sessions or the settings it uses).
"""
