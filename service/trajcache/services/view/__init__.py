"""What the dashboard's 3D view draws, render-ready: the browser needs no URDF loader and no
kinematics of its own.

- `model.py`: a model's links and their collision geometry as the validator holds it
  (primitives by size, meshes as binary STL files of the checked triangles);
- `frames.py`: link world poses along a path, at the service's validation samples, computed
  with the project's own kinematics (a planar base's pose is part of the state);
- `scenes.py`: stored scene versions, by robot and version or by hash;
- `paths.py`: the view of a stored trajectory in the scene it was stored in, and of a plan
  event: its trajectory, or a rejected candidate adapted as it was validated, opened at its
  first failing sample; a plan event whose goal was a pose carries it;
- `cartesian.py`: a stored Cartesian path, with the lines it follows (start and waypoints).
"""
