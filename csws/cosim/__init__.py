"""SUMO co-simulation of fleets with curve speed warning (libsumo, or TraCI for sumo-gui)."""
