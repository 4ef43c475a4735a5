"""The plan flow: lookup, validation, fallback to the planner, and the answer.

- `flow`: the entry points (`answer_plan`, `answer_request`, `plan`, `plan_in_scene`) and the
  spine `_answer` with its steps;
- `attempt`: the request-scoped `PlanAttempt`, its `PhaseClock`, the request and answer types;
- `answers`: the answers of an attempt, each handed to the bookkeeping as its outcome;
- `fallback`: planning in the worker pool, validating and storing what it finds;
- `options`: plan options resolved against the settings (defaults and limits).

What an answer leaves behind (its record, rejections, quality, refusals and metrics) is
`services.bookkeeping`.
"""
