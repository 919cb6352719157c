"""pounding_sweep.scene."""
