"""OpenDRIVE grade and superelevation in the answers: the warning's target and the horizon's CPOIs carry the
curve's mean grade and banking, equal to the closed form of the road's elevation and superelevation cubics."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from markers import marks_its_tests
from test_opendrive import LANE_WIDTH_M, crossings, truth_road

from csws.opendrive.exact import PROFILE_STEP_M
from csws.opendrive.importer import import_opendrive
from csws.opendrive.writer import write_opendrive
from csws.road.roadmap import RoadMap
from csws.standard import DEFAULT_WARNING_RADIUS_M
from service.app import create_app
from service.settings import ServiceSettings

#: Elevation z(s) = a + b s + c s² + d s³ (m) and superelevation e(s) = a + b s (rad) of the test road.
ELEVATION = (12.0, 0.035, -1.5e-5, 4.0e-9)
SUPERELEVATION = (-0.01, -6.0e-5, 0.0, 0.0)
ROAD_LENGTH_M = truth_road().length_m


def elevation_m(s: float) -> float:
    """z(s) of the design."""
    a, b, c, d = ELEVATION
    return a + b * s + c * s**2 + d * s**3


def slope_rate_bound() -> float:
    """The largest |d grade / ds| over the road, 1/m: |2c + 6 d s| is linear in s, largest at an end."""
    _, _, c, d = ELEVATION
    return max(abs(2 * c), abs(2 * c + 6 * d * ROAD_LENGTH_M))


def mean_grade_pct(start_s: float, end_s: float) -> float:
    """The mean slope between two road positions, closed form: (z(s₁) − z(s₀)) / (s₁ − s₀), per cent."""
    return 100.0 * (elevation_m(end_s) - elevation_m(start_s)) / (end_s - start_s)


def mean_banking_pct(start_s: float, end_s: float) -> float:
    """The mean cross slope toward the inside of both lanes' curves, closed form, per cent.

    The road turns left along s and its cross section falls to the left where e < 0: along s the inside is the
    left, against s (turning right) the inside is the road's left too; the cross slope toward it is −tan e, whose
    mean over [s₀, s₁] is (ln cos e(s₁) − ln cos e(s₀)) / (b (s₁ − s₀)) for e = a + b s.
    """
    a, b, _, _ = SUPERELEVATION
    return 100.0 * (math.log(math.cos(a + b * end_s)) - math.log(math.cos(a + b * start_s))) / (b * (end_s - start_s))


def sampling_bound(rate_per_m: float, start_s: float, end_s: float, offset_m: float) -> float:
    """How far the mean of samples every :data:`PROFILE_STEP_M` of a lane's σ can lie from the mean over s of a
    quantity changing by at most ``rate_per_m`` per metre of s, per cent.

    The samples cover the curve less at most one step at each end, and their mean is a trapezoid's within one
    step's change (3 steps' change in all); σ weighs s by 1 − κt, which on the curve varies by
    |t| / R_min, times the quantity's range over the curve.
    """
    spread = rate_per_m * (end_s - start_s)
    return 100.0 * (3 * PROFILE_STEP_M * rate_per_m + abs(offset_m) / 150.0 * spread)


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def sloped_net(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("sloped")
    spec = dataclasses.replace(truth_road("p"), elevation_poly=ELEVATION, superelevation_poly=SUPERELEVATION)
    return import_opendrive(write_opendrive(folder / "p.xodr", [spec]), folder / "p.net.xml").net_path


def _expected(lane_id: str) -> tuple[float, float, float, float]:
    """Closed-form grade and banking of a lane's curve, and the sampling bound of each, per cent."""
    along = lane_id.startswith("-")
    offset_m = -LANE_WIDTH_M / 2 if along else LANE_WIDTH_M / 2
    start_s, end_s = crossings(offset_m, DEFAULT_WARNING_RADIUS_M)
    grade_pct = mean_grade_pct(start_s, end_s) * (1.0 if along else -1.0)
    banking_rate = abs(SUPERELEVATION[1]) / math.cos(0.1) ** 2  # |d tan e / ds| with |e| < 0.1 rad on the road
    return (
        grade_pct,
        mean_banking_pct(start_s, end_s),
        sampling_bound(slope_rate_bound(), start_s, end_s, offset_m),
        sampling_bound(banking_rate, start_s, end_s, offset_m),
    )


def _query(lane_id: str, lane_pos_m: float) -> dict:
    """A passenger car at 130 km/h on ``lane_id``: above V_w of every radius of the truth curve."""
    route = [lane_id.rpartition("_")[0]]
    return {
        "vehicle_id": lane_id,
        "category": "M1",
        "speed_kmh": 130.0,
        "lane_id": lane_id,
        "lane_pos_m": lane_pos_m,
        "route": route,
    }


@pytest.mark.sumo
@pytest.mark.parametrize("lane_id", ["-p_0", "p_0"])
def test_the_warning_target_and_the_horizon_carry_the_curves_grade_and_banking(sloped_net: Path, lane_id: str) -> None:
    """Both directions: the target block and every horizon CPOI of the curve give the closed-form means."""
    grade_pct, banking_pct, grade_bound, banking_bound = _expected(lane_id)
    road_map = RoadMap.load(sloped_net, cache=False)
    (lane_curve,) = road_map.lane_curves(lane_id)
    with TestClient(create_app(ServiceSettings(nets=[sloped_net], state_db=":memory:"))) as client:
        answer = client.post("/v1/warning", json=_query(lane_id, lane_curve.start_pos_m + 1.0)).json()
        ahead = client.get("/v1/horizon", params={"lane_id": lane_id, "lane_pos_m": 0.0, "length_m": 1000.0}).json()
    target = answer["target"]
    assert answer["level"] == 2 and target["curve_id"] == lane_curve.curve_id
    assert target["grade_pct"] == pytest.approx(grade_pct, abs=grade_bound)
    assert target["superelevation_pct"] == pytest.approx(banking_pct, abs=banking_bound)
    cpois = [cpoi for cpoi in ahead["cpois"] if cpoi["curve_id"] == lane_curve.curve_id]
    assert len(cpois) == len(lane_curve.curve.parts)
    assert {(c["grade_pct"], c["superelevation_pct"]) for c in cpois} == {
        (target["grade_pct"], target["superelevation_pct"])
    }


def test_the_bounds_are_tight_enough_to_tell_grade_and_banking_apart() -> None:
    """The sampling bounds the test allows are small beside the figures: a tenth of them or less."""
    for lane_id in ("-p_0", "p_0"):
        grade_pct, banking_pct, grade_bound, banking_bound = _expected(lane_id)
        assert grade_bound < 0.1 * abs(grade_pct) and banking_bound < 0.1 * abs(banking_pct)


@pytest.mark.sumo
def test_a_network_without_opendrive_answers_null(tmp_path: Path) -> None:
    """A fitted network (no exact file beside it): the target and the horizon's CPOIs carry null."""
    net = Path(__file__).resolve().parents[1] / "networks" / "t7_left.net.xml"
    with TestClient(create_app(ServiceSettings(nets=[net], state_db=":memory:"))) as client:
        query = {"vehicle_id": "v", "category": "M1", "speed_kmh": 120.0, "lane_id": "curve_0", "lane_pos_m": 90.0}
        target = client.post("/v1/warning", json=query).json()["target"]
        ahead = client.get("/v1/horizon", params={"lane_id": "approach_0", "lane_pos_m": 0.0}).json()
    assert (target["grade_pct"], target["superelevation_pct"]) == (None, None)
    assert ahead["cpois"] and all(c["grade_pct"] is None and c["superelevation_pct"] is None for c in ahead["cpois"])
