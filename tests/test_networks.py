"""The bundled test tracks (7.4, Tables 3, 4, 7-9) against their generator and their ground truth.

The truth files are written from the authored geometry; these tests check, independently
of the generator's code, that the built SUMO networks carry that geometry: route length,
curve start and end points, and the radius of the driven line (which proves the lanes are
not offset from the authored shape, 7.4.1 and 7.4.2).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import sumolib

from csws.curvature import find_curves
from csws.data import standard_tables
from csws.networks import networks_dir
from csws.networks.generate import compare_network, networks_index, track_specs
from csws.standard import DEFAULT_POLICY

NETWORKS = sorted(path.name.removesuffix(".net.xml") for path in networks_dir().glob("*.net.xml"))
#: Acceleration from rest assumed when checking that the approach is long enough (7.5.1), m/s^2.
MODEST_ACCELERATION_MPS2 = 1.0
#: Time a test speed must be held before the warning distance (7.5.1), s.
STEADY_TIME_S = 3.0


def _truth(name: str) -> dict:
    """The truth file of network ``name``."""
    return json.loads((networks_dir() / f"{name}.truth.json").read_text("utf-8"))


def _net(name: str) -> sumolib.net.Net:
    """The SUMO network ``name``, internal lanes included."""
    return sumolib.net.readNet(str(networks_dir() / f"{name}.net.xml"), withInternal=True)


def _cumulative_length_m(shape: np.ndarray) -> np.ndarray:
    """Arc length at each vertex of a polyline, m."""
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))))


def _fit_circle_radius_m(points: np.ndarray) -> float:
    """Radius of the least-squares circle through ``points`` (algebraic fit), m."""
    x, y = points[:, 0] - points[:, 0].mean(), points[:, 1] - points[:, 1].mean()
    design = np.column_stack((x, y, np.ones_like(x)))
    (a, b, c), *_ = np.linalg.lstsq(design, x**2 + y**2, rcond=None)
    return float(np.sqrt(c + (a / 2) ** 2 + (b / 2) ** 2))


def _route_polyline(net: sumolib.net.Net, edges: list[str]) -> np.ndarray:
    """The lane shapes of the route's edges end to end, each joint point once."""
    shapes = [np.array(net.getEdge(edge).getLanes()[0].getShape()) for edge in edges]
    return np.concatenate([shapes[0]] + [shape[1:] for shape in shapes[1:]])


def _test_demands(truth: dict) -> list[tuple[float, float, int]]:
    """``(test speed km/h, warning distance m, curve number)`` of every test run on this track (7.5).

    A multi-curve S_w is measured to the start of the curve its column names (Tables 7-9);
    on Table 7 the vehicle approaches at the curve-1 speed.
    """
    tables = standard_tables()
    standard = truth["standard"]
    if standard["table"] == 3:
        radius_key = f"{standard['row']['radius_m']:g}"
        return [
            (speed_kmh, distance_m, 1)
            for key in ("table5_single_curve_level1_tests", "table6_single_curve_level2_tests")
            for rows in tables[key][radius_key].values()
            for speed_kmh, distance_m in rows
        ]
    if standard["table"] == 7:
        table7 = next(value for key, value in tables.items() if key.startswith("table7_"))
        rows = [(table7[category]["V_curve1_kmh"], table7[category]["S_w_m"]) for category in tables["categories"]]
    else:
        rows = [(standard["row"]["V_kmh"], standard["row"]["S_w_m"])]
    return [
        (speed_kmh, distance_m, int(column.removeprefix("curve").split("_")[0]))
        for speed_kmh, distances in rows
        for column, distance_m in distances.items()
    ]


def test_every_track_is_shipped_and_indexed() -> None:
    specs = track_specs()
    assert NETWORKS == sorted(spec.name for spec in specs)
    index = json.loads((networks_dir() / "index.json").read_text("utf-8"))
    assert index == networks_index(specs)
    for entry in index["networks"]:
        assert (networks_dir() / entry["truth_file"]).is_file()
        assert _truth(entry["name"])["route"]["edges"] == entry["route"]


@pytest.mark.sumo
def test_a_rebuilt_network_matches_the_shipped_one() -> None:
    spec = next(spec for spec in track_specs() if spec.name == "t9_m1_test1_s")
    assert compare_network(spec, networks_dir()) == []


@pytest.mark.parametrize("name", NETWORKS)
def test_network_carries_its_truth(name: str) -> None:
    truth = _truth(name)
    net = _net(name)
    lanes = {lane["lane"]: lane for lane in truth["lanes"]}
    built_length_m = 0.0
    for edge_id in truth["route"]["edges"]:
        (lane,) = net.getEdge(edge_id).getLanes()
        assert lane.getLength() == pytest.approx(lanes[lane.getID()]["length_m"], abs=0.02)
        assert lane.getSpeed() * 3.6 > max(speed for speed, _, _ in _test_demands(truth))
        built_length_m += lane.getLength()
    assert built_length_m == pytest.approx(truth["route"]["length_m"], abs=0.03)

    for curve in truth["curves"]:
        for on_lane in curve["lanes"]:
            shape = np.array(net.getLane(on_lane["lane"]).getShape())
            lane_s = _cumulative_length_m(shape)
            first, last = np.searchsorted(lane_s, [on_lane["start_pos_m"] - 0.01, on_lane["end_pos_m"] - 0.01])
            assert lane_s[first] == pytest.approx(on_lane["start_pos_m"], abs=0.01)
            assert lane_s[last] == pytest.approx(on_lane["end_pos_m"], abs=0.01)
            assert shape[first] == pytest.approx(curve["start_xy"], abs=0.01)
            assert shape[last] == pytest.approx(curve["end_xy"], abs=0.01)
            assert _fit_circle_radius_m(shape[first : last + 1]) == pytest.approx(curve["radius_m"], rel=0.005)


@pytest.mark.parametrize("name", NETWORKS)
def test_approach_reaches_and_holds_every_test_speed(name: str) -> None:
    """7.5.1: the test speed is reached from rest and held >= 3 s before the warning distance."""
    truth = _truth(name)
    curve_start_s = {curve["number"]: curve["start_s"] for curve in truth["curves"]}
    for speed_kmh, distance_m, number in _test_demands(truth):
        speed_mps = speed_kmh / 3.6
        needed_m = speed_mps**2 / (2 * MODEST_ACCELERATION_MPS2) + STEADY_TIME_S * speed_mps
        assert curve_start_s[number] - distance_m >= needed_m


@pytest.mark.parametrize("name", NETWORKS)
def test_extractor_finds_the_truth(name: str) -> None:
    truth = _truth(name)
    polyline = _route_polyline(_net(name), truth["route"]["edges"])
    found = find_curves(polyline, warning_radius_m=300.0, policy=DEFAULT_POLICY)
    for curve in found:
        assert curve.start_s == pytest.approx(curve.parts[0].start_s, abs=1e-6)
        assert curve.end_s == pytest.approx(curve.parts[-1].end_s, abs=1e-6)
    parts = [part for curve in found for part in curve.parts]
    assert len(parts) == len(truth["curves"])
    for part, expected in zip(parts, truth["curves"], strict=False):
        assert part.start_s == pytest.approx(expected["start_s"], abs=1.0)
        assert part.end_s == pytest.approx(expected["end_s"], abs=1.0)
        assert part.radius_m == pytest.approx(expected["radius_m"], rel=0.01)
