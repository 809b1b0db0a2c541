"""``csws conformance --system fcw``: the forward collision warning's tests run in SUMO, judged and reported.

The tests are GB/T 33577-2017 5.4-5.5 and IVISTA's FCW scenarios.
"""
