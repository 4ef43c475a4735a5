"""Seed jobs: pre-seeding the cache from simulation, in the background of the service."""
