"""What a seed job plans: its request format and its validation (`work` expands it).

A seed job request (the body of `POST /v1/seed-jobs`, or the file of `trajcache seed`) names a
model and says which scenes and which queries to plan, in one of these forms:

Scenes (with `queries`)
- `scenes`: a list of scenes; each is an explicit scene (native `{"objects", "env"}` or a MoveIt
  world, as `PUT /v1/robots/{id}/scene` takes) or a generator spec (below).
- `base_scene` with `variants`: each variant is applied to the base. For an explicit base a
  variant is a scene patch (`{"upsert": [...], "remove": [...], "env": {...}}`, as `PATCH
  /v1/robots/{id}/scene` takes); for a generator base it is generator parameters that override
  the base's (`{"doors_deg": 30}`, `{"env": {"stall_2_door": 0.5}}`).
- `base_scene` with `sweep` (generator base only): `{"param": "doors_deg", "start": 0,
  "stop": 90, "step": 10}` makes one variant per value, `stop` included. `param` is a generator
  parameter (`doors_deg`, `seats_deg`) or `env.<name>` (one environment value).

Generator spec, the reference restroom: `{"generator": "restroom", "doors_deg": 30 | [a, b, c],
"seats_deg": ..., "env": {"stall_1_door": 0.52, "stall_2_seat": 1.57}, "jitter_m": 0.0,
"jitter_seed": null}`. Angles in degrees (0…90, one for every stall or one per stall); `env`
sets single values under the names (and in the unit, radians) the scene records them with.

Queries
- `queries`: `[{"start": [...], "goal": [...], "scene": 2}]`, states ordered as the model's
  `state_names`; a query with `scene` (an index into the scenes) is planned in that scene
  only, one without it in every scene.
- `workload` (instead of `queries` and of any scene): the reference cleaning workload, each call
  planned in the restroom as it is when the call is made (doors opened, seats raised):
  `{"name": "cleaning", "seed": 3}` is one cleaning run (`"perturbed": true` the "real robot"
  one); `{"name": "door_sweep", "seed": 1, "doors_deg": {"start": 0, "stop": 90, "step": 10}}`
  (or a list of angles) is one run per door angle with every door at that angle throughout (the
  paper's pre-seeding). `"limit": n` keeps the first n calls of each run.

`options` (`threshold`, `max_candidates`, `budget_s`, `planner`, `match`) are those of a plan
request; `concurrency` bounds the job's requests in flight (default and maximum: the
`seed_concurrency` setting).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Self

from pydantic import Field, field_validator, model_validator

from trajcache.core.planners import PLANNER_NAMES
from trajcache.core.request_model import RequestModel

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
MAX_LIST = 100_000  # structural bound; the settings bound scenes and work items further


class SeedOptions(RequestModel):
    """Plan options of every request of the job (defaults and bounds from the settings)."""

    threshold: FiniteFloat | None = Field(default=None, gt=0)
    max_candidates: int | None = Field(default=None, ge=1)
    budget_s: FiniteFloat | None = Field(default=None, gt=0)
    planner: str | None = None
    match: Literal["full", "arm"] = "full"

    @field_validator("planner")
    @classmethod
    def _known_planner(cls, name: str | None) -> str | None:
        if name is not None and name.strip().lower() not in PLANNER_NAMES:
            raise ValueError(f"unknown planner {name!r}; use one of {', '.join(PLANNER_NAMES)}")
        return None if name is None else name.strip().lower()


class SeedQuery(RequestModel):
    """One start/goal pair; `scene` restricts it to one scene (index), else every scene."""

    start: list[FiniteFloat] = Field(min_length=1, max_length=64)
    goal: list[FiniteFloat] = Field(min_length=1, max_length=64)
    scene: int | None = Field(default=None, ge=0)


class ValueRange(RequestModel):
    """`start`, `start + step`, … up to `stop` (included)."""

    start: FiniteFloat
    stop: FiniteFloat
    step: FiniteFloat = Field(gt=0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.stop < self.start:
            raise ValueError("stop must not be below start")
        if (self.stop - self.start) / self.step > MAX_LIST:
            raise ValueError(f"the range has more than {MAX_LIST} values")
        return self

    def values(self) -> list[float]:
        """The values of the range."""
        count = math.floor((self.stop - self.start) / self.step + 1e-9) + 1
        return [round(self.start + k * self.step, 9) for k in range(count)]


class Sweep(ValueRange):
    """One variant of a generator base scene per value of `param`."""

    param: str = Field(min_length=1, max_length=120)


class Workload(RequestModel):
    """The reference cleaning workload (see the module docstring)."""

    name: Literal["cleaning", "door_sweep"]
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    doors_deg: list[FiniteFloat] | ValueRange | None = None
    perturbed: bool = False
    limit: int | None = Field(default=None, ge=1)

    @model_validator(mode="after")
    def _fits_name(self) -> Self:
        if self.name == "cleaning" and self.doors_deg is not None:
            raise ValueError("doors_deg is for the door_sweep workload")
        if self.name == "door_sweep" and self.perturbed:
            raise ValueError("perturbed is for the cleaning workload")
        return self

    def door_angles(self) -> list[float]:
        """The door angles of a door sweep (default 0…90 in steps of 10)."""
        if self.doors_deg is None:
            return [float(a) for a in range(0, 91, 10)]
        if isinstance(self.doors_deg, ValueRange):
            return self.doors_deg.values()
        return [float(a) for a in self.doors_deg]


class SeedJobSpec(RequestModel):
    """A seed job request (see the module docstring for the forms it takes)."""

    model_id: str = Field(min_length=1, max_length=64)
    name: str | None = Field(default=None, max_length=200)
    scenes: list[dict[str, Any]] | None = Field(default=None, min_length=1, max_length=MAX_LIST)
    base_scene: dict[str, Any] | None = None
    variants: list[dict[str, Any]] | None = Field(default=None, min_length=1, max_length=MAX_LIST)
    sweep: Sweep | None = None
    queries: list[SeedQuery] | None = Field(default=None, min_length=1, max_length=MAX_LIST)
    workload: Workload | None = None
    options: SeedOptions = Field(default_factory=SeedOptions)
    concurrency: int | None = Field(default=None, ge=1)

    @model_validator(mode="after")
    def _one_form(self) -> Self:
        if (self.queries is None) == (self.workload is None):
            raise ValueError("give either queries or a workload")
        has_scenes = self.scenes is not None or self.base_scene is not None
        if self.workload is not None and (has_scenes or self.variants or self.sweep):
            raise ValueError("a workload brings its own scenes: drop scenes/base_scene")
        if self.queries is not None and (self.scenes is None) == (self.base_scene is None):
            raise ValueError("give either scenes or a base_scene (with variants or a sweep)")
        if (self.variants is not None or self.sweep is not None) and self.base_scene is None:
            raise ValueError("variants and sweep need a base_scene")
        if self.variants is not None and self.sweep is not None:
            raise ValueError("give either variants or a sweep, not both")
        return self
