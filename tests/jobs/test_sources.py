"""A Celery worker's models and scenes: read from the service's database once, then kept."""

from __future__ import annotations

import pytest

from tests.faults.support import ROBOT, app_client, setup_robot, unique_scene
from tests.robots import TWO_JOINT_URDF
from trajcache.geometry.scene.parse import parse_scene
from trajcache.jobs.sources import MissingSourceError, WorkerSources


def test_a_worker_reads_a_model_and_a_stored_scene_once(database_url: str) -> None:
    with app_client(database_url) as client:
        scene_hash = setup_robot(client, unique_scene())
        model_id = client.get(f"/v1/robots/{ROBOT}").json()["model_id"]
    sources = WorkerSources(database_url, models=1)

    model = sources.model(model_id)
    assert (model.model_id, model.urdf) == (model_id, TWO_JOINT_URDF)
    scene = sources.scene(scene_hash, None)
    assert scene.stored and parse_scene(scene.payload).hash == scene_hash
    assert sources.reads == 2
    assert sources.model(model_id) is model and sources.scene(scene_hash, None) is scene
    assert sources.reads == 2  # kept: no second read

    inline = sources.scene("generated", {"objects": []})  # a scene that came with its payload
    assert (inline.payload, inline.stored, sources.reads) == ({"objects": []}, False, 2)


def test_what_the_database_lacks_is_not_found(database_url: str) -> None:
    with app_client(database_url):
        pass  # migrated, empty
    sources = WorkerSources(database_url)
    with pytest.raises(MissingSourceError, match="robot model 'nope' not found"):
        sources.model("nope")
    with pytest.raises(MissingSourceError, match="scene 'f00d' not found"):
        sources.scene("f00d", None)
