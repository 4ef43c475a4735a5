"""trajcache: a shared, collision-validated trajectory cache for mobile manipulators."""

__version__ = "0.1.0"
