"""Validation of trajectories: segment certification, advancement and the validator."""
