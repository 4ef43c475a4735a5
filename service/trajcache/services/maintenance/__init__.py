"""Keeping a cache in shape: eviction, export and import."""
