"""Scene payloads in either format: native (`scene.py`) or a MoveIt `PlanningScene` (`moveit.py`).

Parsing a payload picks its format here, above both, so that neither format's module imports the
other.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import yaml

from trajcache.geometry.errors import SceneError
from trajcache.geometry.scene.fields import parse_env
from trajcache.geometry.scene.frames import NO_FRAMES, SceneFrames
from trajcache.geometry.scene.moveit import is_planning_scene, parse_planning_scene
from trajcache.geometry.scene.payload import parse_native_scene
from trajcache.geometry.scene.scene import Scene

MAX_SCENE_TEXT_BYTES = 16 * 1024 * 1024


def parse_scene(payload: Mapping[str, Any], frames: SceneFrames = NO_FRAMES) -> Scene:
    """Parse a native scene or a MoveIt PlanningScene (whole, `{"world": ...}` or bare list);
    a PlanningScene's objects may also be given in the robot frames `frames` resolves."""
    if not isinstance(payload, Mapping):
        raise SceneError("a scene must be a mapping")
    env = parse_env(payload.get("env"))
    if is_planning_scene(payload):
        return parse_planning_scene(payload, env, frames)
    return parse_native_scene(payload, env)


class _NoAliasLoader(yaml.SafeLoader):
    """Safe YAML loader that refuses aliases (no billion-laughs expansion)."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            raise SceneError("YAML aliases (*ref) are not allowed in scenes")
        return super().compose_node(parent, index)


def load_scene_text(text: str) -> Mapping[str, Any]:
    """The scene document in JSON or YAML text, not yet parsed."""
    if len(text) > MAX_SCENE_TEXT_BYTES:
        raise SceneError(f"scene text exceeds {MAX_SCENE_TEXT_BYTES} bytes")
    try:
        data = json.loads(text)
    except ValueError:
        try:
            data = yaml.load(text, Loader=_NoAliasLoader)
        except yaml.YAMLError as exc:
            raise SceneError(f"scene is neither valid JSON nor YAML: {exc}") from None
    if not isinstance(data, Mapping):
        raise SceneError("a scene document must be a mapping at the top level")
    return data
