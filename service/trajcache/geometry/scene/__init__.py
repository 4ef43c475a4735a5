"""Scenes: world objects and their native and MoveIt formats, and a robot model as its scene
holds it (attached objects, allowed pairs, held joints)."""
