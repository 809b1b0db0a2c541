"""Reads SUMO networks into road maps: lanes, road chains fitted once, paths along them, and map matching."""
