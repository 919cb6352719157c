"""pounding_sweep.identify."""
