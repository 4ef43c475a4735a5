"""Unknown-name messages: the closest valid name (difflib, a synonym, a case slip) and the list."""

from __future__ import annotations

from trajcache.core.suggest import closest, listed, unknown_message


def test_closest_takes_difflib_then_synonyms_then_case_slips() -> None:
    assert closest("panda_joint_2", ["panda_joint1", "panda_joint2"]) == "panda_joint2"
    assert closest("cube", ["box", "sphere"]) is None  # too far apart for difflib
    assert closest("Cube", ["box", "sphere"], synonyms={"cube": "box"}) == "box"
    assert closest("cube", ["sphere"], synonyms={"cube": "box"}) is None  # not a valid name
    assert closest("SHOULDER-JOINT", ["shoulder_joint", "elbow"]) == "shoulder_joint"
    assert closest("zzz", ["box", "sphere"]) is None


def test_unknown_message_names_each_name_and_the_valid_ones() -> None:
    one = unknown_message("field", ["treshold"], ["threshold", "planner"])
    assert one == "unknown field 'treshold' (did you mean 'threshold'?); valid: threshold, planner"
    two = unknown_message("joint", ["elbw", "zzz"], ["elbow"], list_valid=False)
    assert two == "unknown joints 'elbw' (did you mean 'elbow'?), 'zzz'"
    assert listed(str(i) for i in range(40)).endswith("29, …")
