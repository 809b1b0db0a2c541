"""The service's routes, one router per concern: warnings, vehicles, the map, operations, the docs."""
