"""Inverse kinematics for a robot in its current scene (`solve`)."""
