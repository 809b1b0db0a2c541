"""Forward collision warning (GB/T 33577-2017, ISO 15623): its physics, state and target selection."""
