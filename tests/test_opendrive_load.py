"""OpenDRIVE networks load without a fit: chains read their lanes' exact κ (junction stretches bridged), one
curve id per road as on fitted networks, and clothoids given as many linear parts cut into CPOIs by V_w alone."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from markers import marks_its_tests
from test_opendrive import RADIUS_M, truth_road

from csws.curvature import curves_from_profile, profile_from_parts
from csws.curvature.curves import SPIRAL_PIECE_KMH, SPIRAL_SAMPLE_KMH
from csws.engine import Engine, VehicleInput
from csws.opendrive.exact import ExactLane
from csws.opendrive.importer import import_opendrive
from csws.opendrive.profiles import BRIDGE_M, given_exact_profiles
from csws.opendrive.writer import SectionSpec, write_opendrive
from csws.road import chains
from csws.road.roadmap import RoadMap
from csws.standard import DEFAULT_POLICY, Column

#: Two lanes each way: the right ones (driven along s) are 3.5 m and 3.25 m wide.
WIDTHS_M = (3.5, 3.25)


def _exact_lane(bounds: list[float], start_k: list[float], end_k: list[float]) -> ExactLane:
    """An exact lane of the given linear parts (the other fields as an import would fill them for a flat road)."""
    samples = np.array([0.0, bounds[-1]])
    return ExactLane(
        "r", 0.0, -1, True, 0.0, bounds[-1], bounds[-1], np.array(bounds), np.array(start_k), np.array(end_k),
        samples, np.zeros(2), np.zeros(2),
    )  # fmt: skip


def _chain_profile(gap_m: float):
    """The profile given to a chain of an exact clothoid (50 m, κ 0 to 0.01), a junction lane of ``gap_m`` without
    exact κ, and an exact arc of κ 0.02 (40 m)."""
    exact = {"a": _exact_lane([0.0, 50.0], [0.0], [0.01]), "b": _exact_lane([0.0, 40.0], [0.02], [0.02])}
    total_m = 90.0 + gap_m
    xy = np.column_stack((np.linspace(0.0, total_m, 200), np.zeros(200)))
    starts, lengths = np.array([0.0, 50.0, 50.0 + gap_m]), np.array([50.0, gap_m, 40.0])
    return given_exact_profiles(["a", ":j_0", "b"], exact)(np.arange(3), xy, starts, lengths)


def test_a_junction_stretch_is_bridged_linearly_between_the_exact_lanes() -> None:
    """The internal lane between two exact lanes gets one linear part from κ where the first ends to κ where the
    second starts: a clothoid of 5 m from 0.01 to 0.02."""
    profile = _chain_profile(5.0)
    assert profile is not None
    found = [value for p in profile.parts for value in (p.start_s, p.end_s, p.curvature, p.final_curvature)]
    assert found == pytest.approx([0.0, 50.0, 0.0, 0.01, 50.0, 55.0, 0.01, 0.02, 55.0, 95.0, 0.02, 0.02])


def test_a_chain_with_a_longer_stretch_without_exact_curvature_is_left_to_the_fit() -> None:
    assert _chain_profile(BRIDGE_M + 1.0) is None
    no_exact = given_exact_profiles(["x"], {})(np.arange(1), np.zeros((2, 2)), np.zeros(1), np.ones(1))
    assert no_exact is None


def _clothoid_speeds(radius_m: np.ndarray) -> np.ndarray:
    """V_w of every column and level at each radius, ``(6, n)``, km/h."""
    return np.concatenate(
        [DEFAULT_POLICY.warning_speeds_kmh(radius_m, np.full(len(radius_m), i)) for i in range(len(Column))]
    )


@settings(max_examples=40, deadline=None)
@given(
    radius_m=st.floats(20.0, 400.0),
    length_m=st.floats(15.0, 120.0),
    cuts=st.lists(st.floats(0.01, 0.99), min_size=1, max_size=30, unique=True),
)
# The arc after the clothoid ends a hair off its curvature (a spiral part in all but rounding): it is one piece.
@example(radius_m=71.0, length_m=68.17008052741173, cuts=[0.1564222228995652, 0.5715151316186632, 0.1, 0.25])
def test_a_clothoid_in_many_linear_parts_is_cut_into_pieces_by_warning_speed(
    radius_m: float, length_m: float, cuts: list[float]
) -> None:
    """A clothoid from a straight into an arc, given as many linear parts on the same κ line: its CPOIs cover the
    curve end to end, each at the clothoid's radius at its start, neighbours' V_w less than 1 km/h apart in every
    column, and not many more of them than the clothoid given as one part has: a piece ends one sample of
    about :data:`SPIRAL_SAMPLE_KMH` before V_w has moved by 1 km/h, whichever way the samples fall."""
    rate = 1.0 / radius_m / length_m
    bounds = np.unique([0.0, *(c * length_m for c in cuts), length_m, length_m + 50.0])  # no empty part
    kappa = np.minimum(bounds * rate, 1.0 / radius_m)
    vertex_s = np.linspace(0.0, bounds[-1], 400)
    split = profile_from_parts(vertex_s, bounds, kappa[:-1], kappa[1:])
    whole = profile_from_parts(vertex_s, bounds[[0, -2, -1]], kappa[[0, -2]], kappa[[-2, -1]])
    (curve,) = curves_from_profile(split, 500.0, policy=DEFAULT_POLICY)
    (one,) = curves_from_profile(whole, 500.0, policy=DEFAULT_POLICY)
    starts = np.array([part.start_s for part in curve.parts])
    assert starts[0] == pytest.approx(1.0 / 500.0 / rate) and curve.parts[-1].end_s == pytest.approx(bounds[-1])
    assert [a.end_s for a in curve.parts[:-1]] == pytest.approx([b.start_s for b in curve.parts[1:]], abs=1e-9)
    true_radius = 1.0 / np.minimum(starts * rate, 1.0 / radius_m)
    assert [part.radius_m for part in curve.parts] == pytest.approx(true_radius.tolist(), rel=1e-9)
    assert np.all(np.abs(np.diff(_clothoid_speeds(true_radius), axis=1)) < SPIRAL_PIECE_KMH)
    assert len(curve.parts) <= math.ceil(len(one.parts) / (1.0 - 2.0 * SPIRAL_SAMPLE_KMH / SPIRAL_PIECE_KMH)) + 1


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def two_lane_net(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("lanes")
    spec = dataclasses.replace(truth_road("r"), sections=(SectionSpec(0.0, (3.5,), WIDTHS_M),))
    return import_opendrive(write_opendrive(folder / "r.xodr", [spec]), folder / "r.net.xml").net_path


def test_the_lanes_of_a_road_name_its_curve_alike_with_their_own_radii(two_lane_net: Path) -> None:
    """Both right lanes list one curve, of one id (the reference lane's), each at its exact radius R − t."""
    road_map = RoadMap.load(two_lane_net, cache=False)
    (inner,), (outer,) = road_map.lane_curves("-r_1"), road_map.lane_curves("-r_0")
    assert inner.curve_id == outer.curve_id
    offsets_m = (WIDTHS_M[0] / 2, WIDTHS_M[0] + WIDTHS_M[1] / 2)  # lane 0 is the outermost: -r_0 is lane -2
    assert inner.curve.min_radius_m == pytest.approx(RADIUS_M + offsets_m[0], abs=1e-3)
    assert outer.curve.min_radius_m == pytest.approx(RADIUS_M + offsets_m[1], abs=1e-3)


def test_a_lane_change_inside_the_curve_keeps_the_warning_of_the_same_curve(two_lane_net: Path) -> None:
    """A truck above V_w on the inner lane changes to the outer one in the curve: the level stays, its target
    names the same curve."""
    road_map = RoadMap.load(two_lane_net, cache=False)
    engine = Engine(road_map)
    (curve,) = road_map.lane_curves("-r_1")
    pos_m = curve.start_pos_m + 10.0
    first = engine.evaluate(VehicleInput("v", "N", 90.0, "-r_1", pos_m, ("-r",), 0.0))
    after = engine.evaluate(VehicleInput("v", "N", 90.0, "-r_0", pos_m + 2.5, ("-r",), 0.1))
    assert first.warning.target is not None and after.warning.target is not None
    assert first.level == after.level == 2
    assert first.warning.target.curve_id == after.warning.target.curve_id == curve.curve_id


def test_the_exact_road_is_not_fitted(two_lane_net: Path, monkeypatch) -> None:
    """Loading the road (no junction) fits nothing: each of its three lanes' chains reads its exact profile."""
    fitted: list[np.ndarray] = []
    original = chains.cached_radius_profiles

    def recording(polylines, *args, **kwargs):
        fitted.extend(polylines)
        return original(polylines, *args, **kwargs)

    monkeypatch.setattr(chains, "cached_radius_profiles", recording)
    road_map = RoadMap.load(two_lane_net, cache=False)
    exact_chains = {road_map.chains.lane_chain[road_map.lane_index(lane_id)] for lane_id in road_map.exact_lanes}
    assert len(exact_chains) == 3 and fitted == []
