"""The seed jobs of docs/preseeding.md and examples/sweep.yaml are whole jobs, not templates:
each parses, passes the seeding spec, and expands for the reference robot (scenes built, states
within its joint limits, within the default settings' bounds)."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml

from trajcache.cli.seed import REFERENCE
from trajcache.core.config import Settings
from trajcache.reference.robot import reference_model
from trajcache.services.seeding.spec import SeedJobSpec
from trajcache.services.seeding.work import expand

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "preseeding.md"
SWEEP = ROOT / "examples" / "sweep.yaml"


def documented_blocks() -> list[tuple[str, str]]:
    """The YAML and JSON code blocks of the page (list items' blocks dedented)."""
    text = DOC.read_text(encoding="utf-8")
    found = re.findall(r"^( *)```(yaml|json)\n(.*?)^\1```", text, re.S | re.M)
    return [(language, textwrap.dedent(body)) for _indent, language, body in found]


def load(language: str, text: str) -> dict[str, Any]:
    loaded = json.loads(text) if language == "json" else yaml.safe_load(text)
    assert isinstance(loaded, dict), text
    return loaded


def as_posted(job: dict[str, Any]) -> dict[str, Any]:
    """The body `trajcache seed` posts: `model: reference` replaced by a model id."""
    job = dict(job)
    assert job.pop("model") == REFERENCE, "the documented jobs are for the reference robot"
    return {"model_id": "reference-model-id", **job}


def check(job: dict[str, Any]) -> int:
    """Validate and expand `job`; its number of plan requests."""
    spec = SeedJobSpec.model_validate(as_posted(job))
    work = expand(spec, model=reference_model(), settings=Settings())
    assert work.items
    return len(work.items)


BLOCKS = documented_blocks()


def test_the_page_has_its_examples() -> None:
    assert len(BLOCKS) >= 7


@pytest.mark.parametrize(
    ("language", "text"), BLOCKS, ids=[f"block{i}" for i in range(len(BLOCKS))]
)
def test_every_documented_job_validates_for_the_reference_robot(language: str, text: str) -> None:
    check(load(language, text))


def test_the_shipped_example_is_on_the_page_and_small() -> None:
    text = SWEEP.read_text(encoding="utf-8")
    assert ("yaml", text) in BLOCKS
    assert check(load("yaml", text)) == 9  # three door angles, three queries


def test_the_commands_name_the_shipped_example() -> None:
    """`trajcache seed X` in the README and the page: X is the shipped file, or FILE."""
    for page in (ROOT / "README.md", DOC):
        named = re.findall(r"trajcache seed ([\w./-]+)", page.read_text(encoding="utf-8"))
        assert "examples/sweep.yaml" in named and set(named) <= {"examples/sweep.yaml", "FILE"}
    assert SWEEP.is_file()
