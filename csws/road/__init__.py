"""The road map: SUMO networks read into lanes, road chains fitted once, paths along them, and map matching."""
