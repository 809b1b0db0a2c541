"""Forward collision warning (GB/T 33577-2017, ISO 15623): its physics, state, target selection, and the
warning of a vehicle (:mod:`csws.fcw.tracker`) or a fleet (:mod:`csws.fcw.fleet`) from a sensor's object list."""
