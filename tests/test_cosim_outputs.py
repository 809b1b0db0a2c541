"""What ``csws cosim`` writes keeps its word: curve entries only at or above the level-1 warning speed,
lon/lat on geo-referenced networks, the FCD export, command lines that would ignore an option refused.

The curve-entry scenario is driven here in closed form on the R 120 m test track (the engine in this
process, no SUMO), so the time and speed of every entry are known before the run.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pyproj
import pytest
from builders import UTM32, write_geo_track
from hypothesis import given
from hypothesis import strategies as st
from markers import marks_its_tests

from csws.cli import main as csws_main
from csws.cosim.evaluators import FleetWarnings, LibraryEvaluator, no_targets
from csws.cosim.fcd import FcdWriter
from csws.cosim.geo import network_location
from csws.cosim.recording import Streams, Tracker, record_step
from csws.cosim.records import ENTRY_COLUMNS, EVENT_COLUMNS, TIMESERIES_COLUMNS, StepValues, Summary
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.cosim.sumo import FleetState, sumo_arguments
from csws.engine import Engine, EngineSettings
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.sumo.binaries import sumo_binary
from csws.warning.rules import WarningSettings

# ------------------------------------------------------------------ the R 120 m track (single_r120_left.truth.json)
TRACK_NET = networks_dir() / "single_r120_left.net.xml"
ROUTE = ("approach", "curve", "runout")
#: Where each lane starts along the route, m: approach_0, curve_0, runout_0.
LANE_STARTS_M = (("approach_0", 0.0), ("curve_0", 900.0), ("runout_0", 1196.342175))
#: The curve: an arc of R 120 m turning left from (1000, 0), heading east, over 96.34 m.
CURVE_START_M, CURVE_LENGTH_M, RADIUS_M = 1000.0, 96.342175, 120.0
#: T/ITS 0091-2018 Table 1: the level-1 warning speed of an M1 vehicle at R = 120 m, km/h.
V_W1_M1_R120_KMH = 83.0
STEP_S = 0.1


def _lane_at(s_m: float) -> tuple[str, float]:
    """The lane and lane position of route distance ``s_m``."""
    lane_id, start_m = next((lane, start) for lane, start in reversed(LANE_STARTS_M) if s_m >= start)
    return lane_id, s_m - start_m


def _xy_at(s_m: float) -> tuple[float, float]:
    """Network x, y of route distance ``s_m`` on the lane's axis, up to the curve's end."""
    if s_m <= CURVE_START_M:
        return s_m, 0.0
    turned = (s_m - CURVE_START_M) / RADIUS_M
    return CURVE_START_M + RADIUS_M * math.sin(turned), RADIUS_M * (1.0 - math.cos(turned))


def _fleet(time_s: float, s_m: dict[str, float], speed_kmh: dict[str, float]) -> FleetState:
    """The step as SUMO would give it: every vehicle an M1 on the track's route."""
    ids = list(s_m)
    lanes = [_lane_at(s_m[v]) for v in ids]
    xy = [_xy_at(s_m[v]) for v in ids]
    return FleetState(
        time_s=time_s,
        vehicle_id=ids,
        category=["M1"] * len(ids),
        lane_id=[lane for lane, _ in lanes],
        route_edges=[ROUTE] * len(ids),
        lane_pos_m=np.array([pos for _, pos in lanes]),
        speed_mps=np.array([speed_kmh[v] / 3.6 for v in ids]),
        x_m=np.array([x for x, _ in xy]),
        y_m=np.array([y for _, y in xy]),
        odometer_m=np.array([s_m[v] for v in ids]),
        departed=(),
        arrived=(),
        skipped=(),
    )


#: Each vehicle's speed, km/h, by route distance: ``fast`` enters 7 km/h above V_w1; ``held`` is warned at
#: 90 km/h, slows to 82.5 km/h 15 m before the curve (inside the release margin of 1 km/h below V_w1, so the
#: warning stays on) and enters below V_w1; ``slow`` is never near V_w1.
SPEED_PROFILES_KMH = {
    "fast": lambda s_m: 90.0,
    "held": lambda s_m: 90.0 if s_m < CURVE_START_M - 15.0 else 82.5,
    "slow": lambda s_m: 70.0,
}
START_M = 700.0


@pytest.fixture(scope="module")
def driven(tmp_path_factory) -> tuple[Path, list[tuple[float, str, float]]]:
    """The three vehicles driven from 700 m to 1,060 m, every step evaluated and recorded as a run does;
    the output folder and the (time, vehicle, speed) of every step the engine said a vehicle was inside
    a triggering curve part."""
    out = tmp_path_factory.mktemp("entries")
    engine = Engine(RoadMap.load(TRACK_NET), EngineSettings(warning=WarningSettings(update_period_s=STEP_S)))
    evaluator = LibraryEvaluator(engine)
    streams, tracker, summary = Streams.open(out, "none", False), Tracker(), Summary()
    s_m = dict.fromkeys(SPEED_PROFILES_KMH, START_M)
    inside = []
    for step in range(1, 10_000):
        time_s = round(step * STEP_S, 6)
        speed_kmh = {v: profile(s_m[v]) for v, profile in SPEED_PROFILES_KMH.items()}
        s_m = {v: s_m[v] + speed_kmh[v] / 3.6 * STEP_S for v in s_m}
        if min(s_m.values()) > CURVE_START_M + 60.0:
            break
        fleet = _fleet(time_s, s_m, {v: SPEED_PROFILES_KMH[v](s_m[v]) for v in s_m})
        warnings = evaluator(fleet)
        inside += [(time_s, fleet.vehicle_id[i], fleet.speed_mps[i] * 3.6) for i, *_ in warnings.entries]
        record_step(fleet, warnings, None, {}, tracker, summary, streams, sampled=False)
    streams.close()
    return out, inside


def _entries(out: Path) -> list[dict[str, str]]:
    with open(out / "entries.csv", newline="") as file:
        return list(csv.DictReader(file))


def test_a_vehicle_the_release_rule_keeps_warned_below_v_w_is_no_curve_entry(driven) -> None:
    out, inside = driven
    # The engine does hold the slowed vehicle's warning inside the curve below V_w1 ...
    held = [speed_kmh for _, vehicle, speed_kmh in inside if vehicle == "held"]
    assert held and max(held) < V_W1_M1_R120_KMH
    # ... and the never-warned one never triggers.
    assert not [vehicle for _, vehicle, _ in inside if vehicle == "slow"]
    entries = _entries(out)
    assert [row["vehicle_id"] for row in entries] == ["fast"]
    assert all(float(row["excess_kmh"]) >= 0.0 for row in entries)


def test_the_fast_vehicles_entry_is_where_and_how_fast_it_entered(driven) -> None:
    out, _ = driven
    (entry,) = _entries(out)
    # The step at which it is first past the curve's start, in closed form: 90 km/h from 700 m.
    entered_s = STEP_S * math.ceil((CURVE_START_M - START_M) / (90.0 / 3.6) / STEP_S)
    assert float(entry["time_s"]) == pytest.approx(entered_s, abs=STEP_S + 1e-9)
    assert float(entry["speed_kmh"]) == pytest.approx(90.0)
    assert float(entry["level1_warning_speed_kmh"]) == pytest.approx(V_W1_M1_R120_KMH, abs=0.5)
    assert float(entry["excess_kmh"]) == pytest.approx(90.0 - float(entry["level1_warning_speed_kmh"]), abs=1e-9)
    assert float(entry["radius_m"]) == pytest.approx(RADIUS_M, rel=0.02)
    # Where: on the curve's lane, just past its start at (1000, 0).
    assert entry["lane_id"] == "curve_0" and 100.0 <= float(entry["lane_pos_m"]) < 100.0 + 90.0 / 3.6 * STEP_S
    assert float(entry["x_m"]) == pytest.approx(CURVE_START_M, abs=90.0 / 3.6 * STEP_S)
    assert float(entry["y_m"]) == pytest.approx(0.0, abs=0.1)


# ------------------------------------------------------------------ lon/lat on a geo-referenced network
#: A car faster than the Table 7 track's curves allow, so that it is warned and enters them too fast.
GEO_ROUTES = """<routes>
  <vType id="car" vClass="passenger" maxSpeed="30" accel="3" decel="6" sigma="0"/>
  <route id="track" edges="approach curve runout"/>
  <vehicle id="car0" type="car" route="track" depart="0" departSpeed="max"/>
  <vehicle id="car1" type="car" route="track" depart="5" departSpeed="max"/>
</routes>
"""


GEO_STEP_S = 0.2


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def geo_run(tmp_path_factory) -> Path:
    """Two cars over the geo-referenced Table 7 track (network (0, 0) at UTM 32N (550000, 5635000))."""
    folder = tmp_path_factory.mktemp("geo")
    (folder / "track.rou.xml").write_text(GEO_ROUTES)
    scenario = Scenario(None, write_geo_track(folder), (folder / "track.rou.xml",))
    cosimulate(
        CosimConfig(scenario, folder / "out", step_length_s=GEO_STEP_S, timeseries="csv", fcd=folder / "fcd.xml")
    )
    return folder / "out"


def _utm32_to_lonlat(x_m: float, y_m: float) -> tuple[float, float]:
    """Longitude and latitude of a network position of the geo track: UTM 32N inverted by pyproj itself."""
    return pyproj.Proj(UTM32)(x_m + 550_000.0, y_m + 5_635_000.0, inverse=True)


def test_every_csv_output_of_a_geo_referenced_network_has_lon_lat_after_x_y(geo_run) -> None:
    for name in ("timeseries.csv", "warnings.csv", "entries.csv"):
        with open(geo_run / name, newline="") as file:
            header = next(csv.reader(file))
        after = header.index("y_m")
        assert header[after - 1 : after + 3] == ["x_m", "y_m", "lon", "lat"], name
    assert json.loads((geo_run / "summary.json").read_text())["scenario"]["geo_referenced"] is True


def test_lon_lat_are_the_networks_projection_of_x_y(geo_run) -> None:
    rows = [row for name in ("timeseries.csv", "warnings.csv", "entries.csv") for row in _csv_rows(geo_run / name)]
    assert len(_csv_rows(geo_run / "entries.csv")) >= 2 and len(_csv_rows(geo_run / "warnings.csv")) >= 2
    for row in rows:
        lon, lat = _utm32_to_lonlat(float(row["x_m"]), float(row["y_m"]))
        assert float(row["lon"]) == pytest.approx(lon, abs=1e-9) and float(row["lat"]) == pytest.approx(lat, abs=1e-9)
    # Near Bad Hersfeld: UTM 32N (550 km, 5,635 km) is about 9.7 E, 50.9 N.
    assert all(9.5 < float(row["lon"]) < 9.9 and 50.8 < float(row["lat"]) < 51.0 for row in rows)


@pytest.mark.sumo
def test_without_a_time_series_the_events_still_have_lon_lat(geo_run, tmp_path) -> None:
    """A step that keeps no time-series row reads x, y only for the vehicles with an event: their rows,
    lon/lat included, are those of the run that read every position."""
    folder = geo_run.parent
    scenario = Scenario(None, folder / "t7_geo.net.xml", (folder / "track.rou.xml",))
    cosimulate(CosimConfig(scenario, tmp_path, step_length_s=GEO_STEP_S, timeseries="none"))
    for name in ("warnings.csv", "entries.csv"):
        assert (tmp_path / name).read_bytes() == (geo_run / name).read_bytes(), name


def test_only_a_network_with_a_projection_gets_lon_lat(tmp_path) -> None:
    """The test tracks have none (``projParameter="!"``); Bad Hersfeld, gzipped, has UTM's."""
    assert network_location(TRACK_NET) is None
    city = network_location(networks_dir() / "badhersfeld.net.xml.gz")
    assert city is not None
    lon, lat = city.lonlat(np.array([0.0, np.nan]), np.array([0.0, np.nan]))
    assert lon[1] is None and lat[1] is None and 9.6 < lon[0] < 9.9 and 50.8 < lat[0] < 50.95
    streams = Streams.open(tmp_path, "csv", False, geo=False)
    streams.close()
    for name, columns in (("timeseries.csv", TIMESERIES_COLUMNS), ("warnings.csv", EVENT_COLUMNS)):
        assert (tmp_path / name).read_text() == ",".join(columns) + "\n"
    assert (tmp_path / "entries.csv").read_text() == ",".join(ENTRY_COLUMNS) + "\n"
    assert "lon" not in ENTRY_COLUMNS + EVENT_COLUMNS + TIMESERIES_COLUMNS


# ------------------------------------------------------------------ the FCD export
def _fcd(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    """Every vehicle of an FCD file by (time, id), its attributes as written."""
    root = ElementTree.parse(path).getroot()
    assert root.tag == "fcd-export"
    return {
        (timestep.get("time"), vehicle.get("id")): dict(vehicle.attrib)
        for timestep in root.iter("timestep")
        for vehicle in timestep.iter("vehicle")
    }


@pytest.mark.sumo
def test_the_fcd_export_is_sumos_own_with_the_warnings_added(geo_run, tmp_path) -> None:
    """SUMO's own --fcd-output of the same scenario gives the same vehicles at the same times with the same
    x, y, angle, type, speed, lane position and lane; the warning level is the time series'."""
    folder = geo_run.parent
    sumo = tmp_path / "sumo-fcd.xml"
    arguments = sumo_arguments(None, folder / "t7_geo.net.xml", [folder / "track.rou.xml"], GEO_STEP_S, 0, None)
    subprocess.run([str(sumo_binary("sumo")), *arguments, "--fcd-output", str(sumo)], check=True, timeout=120)
    ours, theirs = _fcd(folder / "fcd.xml"), _fcd(sumo)
    assert len(ours) > 100 and set(ours) <= set(theirs)
    for key, vehicle in ours.items():
        for name in ("x", "y", "angle", "speed", "pos"):
            assert float(vehicle[name]) == pytest.approx(float(theirs[key][name]), abs=0.011), (key, name)
        assert (vehicle["type"], vehicle["lane"]) == (theirs[key]["type"], theirs[key]["lane"])
    # SUMO labels a step's state with the time the step began; the time series with the time after it.
    rows = {
        (f"{float(row['time_s']) - GEO_STEP_S:.2f}", row["vehicle_id"]): row
        for row in _csv_rows(geo_run / "timeseries.csv")
    }
    assert set(rows) == set(ours)
    for key, vehicle in ours.items():
        row = rows[key]
        assert (vehicle["csws_level"], vehicle["csws_state"]) == (row["level"], row["state"])
        assert float(vehicle["lon"]) == pytest.approx(float(row["lon"]), abs=1e-7)
        assert float(vehicle["lat"]) == pytest.approx(float(row["lat"]), abs=1e-7)
    assert {vehicle["csws_level"] for vehicle in ours.values()} == {"0", "1", "2"}


@pytest.mark.sumo
def test_over_traci_the_fcd_export_is_the_same(geo_run, tmp_path) -> None:
    """TraCI's subscriptions read the angle and type as libsumo's getters do: the same file, byte for byte."""
    folder = geo_run.parent
    scenario = Scenario(None, folder / "t7_geo.net.xml", (folder / "track.rou.xml",))
    config = CosimConfig(scenario, tmp_path / "out", step_length_s=GEO_STEP_S, timeseries="none", interface="traci")
    cosimulate(replace(config, fcd=tmp_path / "fcd.xml"))
    assert (tmp_path / "fcd.xml").read_bytes() == (folder / "fcd.xml").read_bytes()


def test_an_fcd_timestep_carries_the_fcw_level_and_any_vehicle_id(tmp_path) -> None:
    """Ids, types and lanes are XML-quoted; with the forward collision warning each vehicle has its level;
    the time is SUMO's, one step before ``time_s``; the closing tag comes with ``close``."""
    fleet = FleetState(
        time_s=12.3,
        vehicle_id=['a&"b', "<c>"],
        category=["M1", "N"],
        lane_id=["e_0", "f&g_1"],
        route_edges=[("e",), ("f&g",)],
        lane_pos_m=np.array([1.234, 5.0]),
        speed_mps=np.array([20.004, 0.0]),
        x_m=np.array([10.0, -3.456]),
        y_m=np.array([2.0, 7.891]),
        odometer_m=np.zeros(2),
        departed=(),
        arrived=(),
        skipped=(),
        type_id=["car", "truck'1"],
        angle_deg=np.array([90.0, 359.996]),
    )
    warnings = FleetWarnings(["active", "active"], [0, 2], no_targets(2), [])
    writer = FcdWriter(tmp_path / "sub" / "fcd.xml", 0.1)
    writer.append(StepValues.of(fleet), warnings, [1, 0])
    writer.close()
    (timestep,) = ElementTree.parse(tmp_path / "sub" / "fcd.xml").getroot()
    assert timestep.get("time") == "12.20"
    first, second = (dict(vehicle.attrib) for vehicle in timestep)
    assert first == {
        "id": 'a&"b',
        "x": "10.00",
        "y": "2.00",
        "angle": "90.00",
        "type": "car",
        "speed": "20.00",
        "pos": "1.23",
        "lane": "e_0",
        "csws_state": "active",
        "csws_level": "0",
        "fcw_level": "1",
    }
    assert (second["id"], second["lane"], second["type"]) == ("<c>", "f&g_1", "truck'1")
    assert (second["csws_level"], second["fcw_level"], second["angle"], second["x"]) == ("2", "0", "360.00", "-3.46")


CITY = network_location(networks_dir() / "badhersfeld.net.xml.gz")
_POSITION_M = st.one_of(st.floats(-5_000.0, 15_000.0), st.just(math.nan))


@given(st.lists(st.tuples(_POSITION_M, _POSITION_M), min_size=1, max_size=20))
def test_lon_lat_go_back_to_x_y_and_exist_only_where_x_y_do(positions) -> None:
    """Whatever the mix of read and unread positions, each read one's lon/lat projects back onto it (1 mm)
    and each unread one (NaN) has none."""
    assert CITY is not None
    x_m, y_m = (np.array(column) for column in zip(*positions, strict=True))
    lon, lat = CITY.lonlat(x_m, y_m)
    for row, (x, y) in enumerate(positions):
        if math.isnan(x) or math.isnan(y):
            assert lon[row] is None and lat[row] is None
        else:
            assert CITY.lonlat_to_xy(lon[row], lat[row]) == pytest.approx((x, y), abs=1e-3)


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


# ------------------------------------------------------------------ command lines that would ignore an option
@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--routes", "{tmp}/a.rou.xml"], "--routes needs --net"),
        (["--vehicles", "5", "--sumocfg", "{tmp}/x.sumocfg"], "--vehicles generates a fleet on the bundled"),
        (["--timeseries", "none", "--timeseries-every", "5"], "--timeseries-every thins the time series"),
        (["--api-key-file", "{tmp}/key"], "--api-key-file is for a service"),
    ],
)
def test_an_option_the_run_would_ignore_is_one_error_line(arguments, message, tmp_path, capsys) -> None:
    (tmp_path / "key").write_text("secret\n")
    argv = ["cosim", "--out", str(tmp_path / "out"), *(a.format(tmp=tmp_path) for a in arguments)]
    assert csws_main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"csws: error: {message}") and captured.err.count("\n") == 1
    assert not (tmp_path / "out" / "summary.json").exists()


# ------------------------------------------------------------------ the command's default time series
@pytest.mark.sumo
def test_the_command_keeps_one_step_a_second_by_default(tmp_path, capsys) -> None:
    """Without ``--timeseries-every`` the time series keeps one step per simulated second (every 10th of
    0.1 s), the cheap sampled series a study needs; the warnings still come from every step."""
    out = tmp_path / "out"
    argv = ["cosim", "--out", str(out), "--vehicles", "20", "--end", "5", "--timeseries", "csv"]
    assert csws_main(argv) == 0
    capsys.readouterr()
    times_s = sorted({float(row["time_s"]) for row in _csv_rows(out / "timeseries.csv")})
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timeseries"] == {"format": "csv", "every_steps": 10}
    assert len(times_s) == math.ceil(summary["steps"] / 10) > 1
    assert np.diff(times_s) == pytest.approx(np.ones(len(times_s) - 1), abs=1e-9)
