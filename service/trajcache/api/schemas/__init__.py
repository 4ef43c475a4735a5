"""Request and response bodies of the v1 API (pydantic v2), one module per resource.

`models` (robot models), `robots` (robots and their scenes), `trajectories`, `stats`
(statistics, plan events, trajectory usage), `health`, `errors` (every error answer);
`common` holds the field types and example values they share. Import from the modules.
"""
