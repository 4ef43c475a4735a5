"""The robot's own link pairs that are not checked for collision, and why."""

from __future__ import annotations

from trajcache.geometry.model.robot import RobotModel
from trajcache.geometry.model.srdf import Srdf


def _rigid_bodies(model: RobotModel) -> list[int]:
    """Body of each link: links joined by fixed joints form one rigid body."""
    group = list(range(len(model.link_names)))

    def find(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    for joint in model.joints:
        if joint.kind == "fixed":
            group[find(joint.child)] = find(joint.parent)
    return [find(link) for link in range(len(group))]


def adjacent_pairs(model: RobotModel) -> set[tuple[int, int]]:
    """Link pairs (i < j, both with geometry) that are adjacent: in one rigid body (links joined
    by fixed joints), or in two bodies joined by a joint. A body without collision geometry that
    only links one parent body to one child body passes adjacency through, as a bare frame in a
    chain does; a bare body with several children joins none of them to each other."""
    body = _rigid_bodies(model)
    geometric = {int(link) for link in model.geometric_links()}
    solid = {body[link] for link in geometric}
    parent: dict[int, int] = {}
    children: dict[int, set[int]] = {}
    for joint in model.joints:
        a, b = body[joint.parent], body[joint.child]
        if a != b:
            parent[b] = a
            children.setdefault(a, set()).add(b)
    neighbours: dict[int, set[int]] = {b: set() for b in solid}
    for b in solid:
        current = b
        while current in parent:
            up = parent[current]
            if up in solid:
                neighbours[b].add(up)
                break
            if len(children.get(up, ())) != 1:
                break
            current = up
    pairs: set[tuple[int, int]] = set()
    links = sorted(geometric)
    for k, a in enumerate(links):
        for b in links[k + 1 :]:
            ba, bb = body[a], body[b]
            if ba == bb or bb in neighbours[ba] or ba in neighbours[bb]:
                pairs.add((a, b))
    return pairs


def rigid_pairs(model: RobotModel) -> set[tuple[int, int]]:
    """Link pairs (i < j, both with geometry) that no planning joint moves relative to each
    other: the planning joints above one are exactly those above the other (the base moves
    every link alike). Their contact is the same in every state, so no motion can change it."""
    parent_joint = {joint.child: joint for joint in model.joints}
    above: list[frozenset[str]] = []  # the planning-driven joints above each link
    for link in range(len(model.link_names)):
        driven: set[str] = set()
        current = link
        while current in parent_joint:
            joint = parent_joint[current]
            if joint.index >= 0:
                driven.add(joint.name)
            current = joint.parent
        above.append(frozenset(driven))
    links = [int(link) for link in model.geometric_links()]
    return {(a, b) for k, a in enumerate(links) for b in links[k + 1 :] if above[a] == above[b]}


def skipped_pairs(model: RobotModel, srdf: Srdf | None) -> dict[tuple[int, int], str]:
    """Link pairs (i < j, both with geometry) whose self-collisions are not checked, and why:
    `adjacent`, `rigid` (`rigid_pairs`) or `srdf` (the SRDF's disable_collisions). Every other
    pair is checked unless the geometry proves it free within the limits (`free_pairs`)."""
    reasons = {pair: "adjacent" for pair in adjacent_pairs(model)}
    for pair in rigid_pairs(model):
        reasons.setdefault(pair, "rigid")
    if srdf is not None:
        index = {name: i for i, name in enumerate(model.link_names)}
        geometric = {int(link) for link in model.geometric_links()}
        for link1, link2, _ in srdf.disabled:
            a, b = index.get(link1), index.get(link2)
            if a is None or b is None or a == b or a not in geometric or b not in geometric:
                continue
            reasons.setdefault((min(a, b), max(a, b)), "srdf")
    return reasons
