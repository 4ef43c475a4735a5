"""Cartesian paths for a robot in its current scene, cached (`path`, `store`)."""
