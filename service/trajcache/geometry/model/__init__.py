"""The robot model: URDF and SRDF, links and joints, forward kinematics, motion bounds, shapes
and their sphere covers and support tables."""
