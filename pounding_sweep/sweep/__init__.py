"""pounding_sweep.sweep."""
