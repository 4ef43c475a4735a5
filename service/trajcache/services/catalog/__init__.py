"""What the cache holds: robot models, robots and their scenes, trajectories, API keys."""
