"""pounding_sweep.engine."""
