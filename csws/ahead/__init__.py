"""Finds the road ahead of a vehicle: its path, the look-ahead distance S_LAD (3.9) and the CPOIs on it (3.11)."""
