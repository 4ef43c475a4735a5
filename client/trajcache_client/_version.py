"""The client's version (the trajcache distribution's)."""

__version__ = "0.1.0"
