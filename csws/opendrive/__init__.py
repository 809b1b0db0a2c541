"""ASAM OpenDRIVE roads: read their plan view, lanes and profiles, give every SUMO lane built from them its exact
curvature, and write such roads for tests and benchmarks."""
