"""``csws cosim --systems csws,fcw``: the forward collision warning in the co-simulation, real SUMO runs.

A truck at 20 m/s approaches a stopped car on the FCW straight track (networks/fcw/); its SUMO
driver brakes late and hard (decel 9 m/s^2), the inattentive driver a warning is for. The
checks: SUMO's own SSM device as an independent TTC, the warning events, the driver-response
model braking on the warning, and the curve warning's files unchanged by FCW.
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pyarrow.parquet as pq
import pytest
from markers import marks_its_tests

from csws.cosim.driver import DriverSettings
from csws.cosim.fcw import FCW_EVENT_COLUMNS
from csws.cosim.records import EVENT_COLUMNS, TIMESERIES_COLUMNS
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.fcw.settings import FcwSettings
from csws.networks import networks_dir
from csws.networks.fleet import fleet_dir, fleet_routes_xml

STRAIGHT_NET = networks_dir() / "fcw" / "fcw_straight.net.xml"
STEP_S = 0.1
END_S = 40.0
LEAD_AT_M = 600.0
LEAD_LENGTH_M = 4.5
SPEED_MPS = 20.0

ROUTES = f"""<routes>
<vType id="truck" vClass="truck" length="12" width="2.5" minGap="2.5" accel="1.5" decel="9" emergencyDecel="9"
 sigma="0" speedFactor="1" speedDev="0" maxSpeed="{SPEED_MPS:g}"
 lcStrategic="-1" lcSpeedGain="0" lcKeepRight="0" lcCooperative="0"/>
<vType id="car" vClass="passenger" length="{LEAD_LENGTH_M:g}" minGap="2.5" sigma="0" speedFactor="1" speedDev="0"/>
<vehicle id="lead" type="car" depart="0" departPos="{LEAD_AT_M:g}" departLane="0" departSpeed="0"><route edges="road"/>
 <stop lane="road_0" endPos="{LEAD_AT_M:g}" duration="1000"/></vehicle>
<vehicle id="sv" type="truck" depart="0" departPos="50" departLane="0" departSpeed="{SPEED_MPS:g}">
 <route edges="road"/></vehicle>
</routes>
"""


def _sumocfg(folder: Path, routes: Path, ssm: Path) -> Path:
    """A configuration with every vehicle carrying SUMO's SSM device, logging TTC below 4 s per step."""
    config = folder / "approach.sumocfg"
    config.write_text(f"""<configuration>
 <input><net-file value="{STRAIGHT_NET}"/><route-files value="{routes}"/></input>
 <output><precision value="6"/></output>
 <ssm_device>
  <device.ssm.probability value="1"/><device.ssm.measures value="TTC"/><device.ssm.thresholds value="4.0"/>
  <device.ssm.trajectories value="true"/><device.ssm.file value="{ssm}"/>
 </ssm_device>
</configuration>
""")
    return config


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def approach(tmp_path_factory) -> dict:
    """The approach without and with the driver-response model (both systems), and SSM's log of the first."""
    folder = tmp_path_factory.mktemp("approach")
    routes = folder / "approach.rou.xml"
    routes.write_text(ROUTES)
    ssm = folder / "ssm.xml"
    runs = {"ssm": ssm}
    for name, driver in (("without", None), ("with", DriverSettings())):
        scenario = (
            Scenario(_sumocfg(folder, routes, ssm), STRAIGHT_NET)
            if driver is None
            else Scenario(None, STRAIGHT_NET, (routes,))
        )
        out = folder / name
        summary = cosimulate(
            CosimConfig(
                scenario,
                out,
                step_length_s=STEP_S,
                end_s=END_S,
                driver=driver,
                systems=("csws", "fcw"),
                timeseries="csv",
            )
        )
        runs[name] = (summary, _rows(out / "timeseries.csv"), _rows(out / "warnings.csv"))
    return runs


def _rows(path: Path) -> list[dict]:
    with path.open(newline="") as stream:
        return list(csv.DictReader(stream))


def _subject(rows: list[dict]) -> list[dict]:
    return [row for row in rows if row["vehicle_id"] == "sv"]


def _true_clearance_m(row: dict) -> float:
    """The subject's front to the lead's rear, from the constructed scenario (one straight lane)."""
    return LEAD_AT_M - LEAD_LENGTH_M - float(row["lane_pos_m"])


def test_csws_ttc_agrees_with_sumos_ssm_device(approach):
    ours = {round(float(row["time_s"]), 6): row for row in _subject(approach["without"][1])}
    conflicts = [
        c
        for c in ElementTree.parse(approach["ssm"]).getroot().iter("conflict")
        if c.get("ego") == "sv" and c.get("foe") == "lead"
    ]
    assert len(conflicts) == 1
    times = [float(t) for t in conflicts[0].find("timeSpan").get("values").split()]
    ssm_ttc = conflicts[0].find("TTCSpan").get("values").split()
    compared = 0
    for time_s, value in zip(times, ssm_ttc, strict=False):
        now, after = ours.get(round(time_s, 6)), ours.get(round(time_s + STEP_S, 6))
        if value == "NA" or not now or not after or not now["fcw_ttc_s"] or not after["fcw_ttc_s"]:
            continue
        # The range changes by one step's closing in one step: TTC within that step's worth.
        closing_mps = -float(now["fcw_range_rate_mps"])
        one_step_s = abs(float(now["fcw_range_m"]) - float(after["fcw_range_m"])) / closing_mps
        assert abs(float(now["fcw_ttc_s"]) - float(value)) <= one_step_s + 1e-6, time_s
        # SSM labels a step with the time it started at, the vehicles already moved: csws's next row.
        assert float(after["fcw_ttc_s"]) == pytest.approx(float(value), abs=1e-5), time_s
        compared += 1
    assert compared >= 20


def test_fcw_warnings_are_recorded_beside_the_curve_warning(approach):
    summary, timeseries, events = approach["without"]
    assert tuple(timeseries[0]) == (
        *TIMESERIES_COLUMNS,
        "fcw_state",
        "fcw_level",
        "fcw_target_id",
        "fcw_range_m",
        "fcw_range_rate_mps",
        "fcw_ttc_s",
    )
    assert tuple(events[0]) == EVENT_COLUMNS + FCW_EVENT_COLUMNS
    assert summary["systems"] == ["csws", "fcw"]
    assert summary["fcw"] == {"by_level": {"level1": 1, "level2": 1}, "vehicles_warned": 1}
    assert [e["event"] for e in events] == ["fcw_onset", "fcw_change", "fcw_end"]
    settings = FcwSettings()
    for event in events:
        assert event["vehicle_id"] == "sv" and event["fcw_target_id"] == "lead" and event["curve_id"] == ""
        range_m = float(event["fcw_range_m"])
        assert range_m == pytest.approx(_true_clearance_m(event), abs=1e-6)
        assert float(event["fcw_ttc_s"]) == pytest.approx(range_m / -float(event["fcw_range_rate_mps"]), rel=1e-9)
    # At constant speed toward a stopped lead, a_req = v^2 / (2 (x_c - v T_resp)) (formula (4)) and
    # TTC = x_c / v (formula (2)): the collision warning comes on in the first step in which a_req
    # reaches its threshold, the preliminary one in the first in which a_req reaches its threshold
    # at a TTC of at most 4 s (4.5.5 e suppresses the preliminary warning above it).
    rows = _subject(timeseries)
    for event, threshold, ttc_limit_s in zip(
        events[:2],
        (settings.preliminary_a_req_mps2, settings.collision_a_req_mps2),
        (settings.max_ttc_s, math.inf),
        strict=False,
    ):
        step = next(i for i, row in enumerate(rows) if row["time_s"] == event["time_s"])
        for row, reached in ((rows[step], True), (rows[step - 1], False)):
            clearance_m = _true_clearance_m(row)
            a_req = SPEED_MPS**2 / (2.0 * (clearance_m - SPEED_MPS * settings.reaction_time_s))
            assert (a_req >= threshold and clearance_m / SPEED_MPS <= ttc_limit_s) is reached


def test_the_driver_brakes_on_the_fcw_warning_and_stops_short_of_the_lead(approach):
    _, without_rows, _ = approach["without"]
    _, with_rows, with_events = approach["with"]
    settings = DriverSettings()
    onset_s = float(with_events[0]["time_s"])
    rows = _subject(with_rows)
    commanded = [row for row in rows if row["commanded_speed_kmh"]]
    # After the reaction time the driver brakes at its deceleration, before SUMO's own driver would.
    assert float(commanded[0]["time_s"]) == pytest.approx(onset_s + settings.reaction_s, abs=1e-6)
    first = rows.index(commanded[0])  # commanded after this step's reading: the next step is slower
    for before, row in zip(rows[first : first + 10], rows[first + 1 : first + 11], strict=False):
        drop_mps = (float(before["speed_kmh"]) - float(row["speed_kmh"])) / 3.6
        assert drop_mps == pytest.approx(settings.decel_mps2 * STEP_S, abs=1e-6)

    def stopped_at_m(subject_rows: list[dict]) -> float:
        return _true_clearance_m(next(row for row in subject_rows if float(row["speed_kmh"]) < 1.0))

    # It stops where the reaction at the test speed and the braking at its deceleration end, from the warning's
    # clearance (within a step's travel), short of where SUMO's own driver stops.
    travel_m = SPEED_MPS * settings.reaction_s + SPEED_MPS**2 / (2.0 * settings.decel_mps2)
    expected_m = float(with_events[0]["fcw_range_m"]) - travel_m
    assert stopped_at_m(rows) == pytest.approx(expected_m, abs=SPEED_MPS * STEP_S)
    assert stopped_at_m(rows) > stopped_at_m(_subject(without_rows)) + SPEED_MPS * STEP_S
    assert min(map(_true_clearance_m, rows)) > 0.0


@pytest.mark.sumo
def test_the_curve_warnings_files_are_the_same_with_fcw_on(tmp_path):
    routes = tmp_path / "fleet.rou.xml"
    routes.write_text(fleet_routes_xml(20, period_s=40.0, seed=3))
    scenario = Scenario(None, fleet_dir() / "fleet.net.xml", (routes,))
    runs = {}
    for systems in (("csws",), ("csws", "fcw")):
        out = tmp_path / "-".join(systems)
        cosimulate(CosimConfig(scenario, out, step_length_s=0.2, end_s=120.0, systems=systems))
        runs[systems] = pq.read_table(out / "timeseries"), _rows(out / "warnings.csv")
    (alone, alone_events), (both, both_events) = runs[("csws",)], runs[("csws", "fcw")]
    assert alone.schema.names == list(TIMESERIES_COLUMNS)
    assert both.select(list(TIMESERIES_COLUMNS)).equals(alone)
    curve_events = [{k: row[k] for k in EVENT_COLUMNS} for row in both_events if not row["event"].startswith("fcw_")]
    assert len(alone_events) > 5 and curve_events == alone_events


def test_fcw_with_a_service_is_one_error_line(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "csws",
            "cosim",
            "--systems",
            "csws,fcw",
            "--service",
            "http://127.0.0.1:9",
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode != 0
    assert result.stderr.strip().splitlines() == [
        "csws: error: the forward collision warning is evaluated in this process only: drop --service, "
        "or run --systems csws with it"
    ]
