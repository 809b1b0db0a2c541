"""``csws conformance --system fcw``: the forward collision warning's tests (GB/T 33577-2017 5.4-5.5,
IVISTA's FCW scenarios) in SUMO, judged and reported."""
