"""pounding_sweep.model."""
