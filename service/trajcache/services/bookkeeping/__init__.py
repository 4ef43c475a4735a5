"""What happens after an answer: usage counters, plan events and stored quality, written in
order off the request's thread, and the ranking facts that bookkeeping keeps current.

- `records`, `record_batch`: the ordered writer of usage counters and plan events;
- `ranking_facts`: ranking facts kept in memory briefly.

Below the plan flow and the service context, which holds the writer and the facts: a concept
records through it without knowing the flow.
"""
