"""Collision: bodies and bound tables, distance lower bounds, narrow phase, pairs proven free, the
compiled kernels and the collision checker."""
