"""SUMO's programs: where the ``eclipse-sumo`` wheel put them, and building networks with netconvert."""
