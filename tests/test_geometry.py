"""Constructed road geometry: clothoids against a brute-force integration of their curvature."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.geometry import arc, clothoid, curvature_at, pose_at, straight


def _integrated_pose(curvature_of_s, length_m: float, steps: int = 400_000) -> tuple[float, float, float]:
    """x, y and heading at ``length_m`` by the trapezoidal rule on a fine grid: independent of the quadrature."""
    s = np.linspace(0.0, length_m, steps + 1)
    kappa = curvature_of_s(s)
    heading = np.concatenate(([0.0], np.cumsum((kappa[1:] + kappa[:-1]) / 2.0 * np.diff(s))))
    return float(np.trapezoid(np.cos(heading), s)), float(np.trapezoid(np.sin(heading), s)), float(heading[-1])


@settings(max_examples=20, deadline=None)
@given(st.floats(10.0, 120.0), st.floats(25.0, 500.0), st.sampled_from(["left", "right"]))
def test_a_spiral_into_an_arc_ends_where_its_curvature_takes_it(
    spiral_m: float, radius_m: float, direction: str
) -> None:
    sign = 1.0 if direction == "left" else -1.0
    pieces = [straight(20.0), clothoid(spiral_m, math.inf, radius_m, direction), arc(radius_m, 30.0, direction)]
    length_m = 20.0 + spiral_m + radius_m * math.radians(30.0)

    def truth(s: np.ndarray) -> np.ndarray:
        return sign * np.clip((s - 20.0) / spiral_m, 0.0, 1.0) / radius_m

    x, y, heading = pose_at(pieces, np.array([length_m]))
    expected = _integrated_pose(truth, length_m)
    assert math.hypot(x[0] - expected[0], y[0] - expected[1]) < 1e-4
    assert abs(heading[0] - expected[2]) < 1e-9
    s = np.linspace(0.0, length_m, 50)
    np.testing.assert_allclose(curvature_at(pieces, s), truth(s), atol=1e-12)


def test_a_clothoid_turns_by_its_mean_curvature_times_its_length() -> None:
    piece = clothoid(60.0, 300.0, 100.0, "right")
    assert piece.radius_m == 100.0
    assert piece.angle_deg == math.degrees((1 / 300 + 1 / 100) / 2 * 60.0)
