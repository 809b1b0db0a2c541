"""The co-simulation: a real SUMO fleet on the bundled fleet network, in-process and over a real service.

Warnings are checked against the standard (Tables 1-2 and formula (1) computed here),
the two evaluation modes against each other, and the output files after SUMO or the
run itself is killed.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree

import pyarrow.parquet as pq
import pytest
from markers import marks_its_tests
from servers import Server

from csws.cosim.categories import category_of
from csws.cosim.driver import DriverSettings
from csws.cosim.evaluators import ServiceError
from csws.cosim.records import ENTRY_COLUMNS, EVENT_COLUMNS, TIMESERIES_COLUMNS
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.cosim.timeseries import TIMESERIES_SCHEMA
from csws.networks.fleet import FLEET_TYPES, fleet_dir, fleet_routes_xml
from csws.standard import Category, kmh_to_mps, warning_distance, warning_speed
from service.keys import add_key

FLEET_NET = fleet_dir() / "fleet.net.xml"
VEHICLES = 200
END_S = 170.0
STEP_S = 0.2


@pytest.fixture(scope="module")
def fleet_routes(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("fleet") / "fleet.rou.xml"
    path.write_text(fleet_routes_xml(VEHICLES, period_s=150.0, seed=1))
    return path


def _config(routes: Path, out: Path, **changes) -> CosimConfig:
    return CosimConfig(Scenario(None, FLEET_NET, (routes,)), out, step_length_s=STEP_S, end_s=END_S, **changes)


@pytest.fixture(scope="module")
@marks_its_tests("slow", "sumo")
def library_run(fleet_routes, tmp_path_factory):
    out = tmp_path_factory.mktemp("library")
    return out, cosimulate(_config(fleet_routes, out))


def _rows(path: Path) -> list[dict]:
    with path.open(newline="") as stream:
        return list(csv.DictReader(stream))


def _timeseries(out: Path) -> list[dict]:
    """The rows of a run's Parquet time series (every part, in order)."""
    return pq.read_table(out / "timeseries").to_pylist()


def test_vehicle_classes_map_to_the_standards_categories():
    assert category_of("passenger") is Category.M1
    assert category_of("bus") is Category.M3 and category_of("coach") is Category.M3
    assert category_of("delivery") is Category.N and category_of("truck") is Category.N
    assert category_of("trailer") is Category.O
    assert category_of("bicycle") is None and category_of("motorcycle") is None
    assert category_of("bus", "M2") is Category.M2
    with pytest.raises(ValueError, match="csws.category"):
        category_of("bus", "L3")


def test_every_vehicle_is_evaluated_with_its_category(library_run):
    out, summary = library_run
    assert summary["complete"] and summary["vehicles_evaluated"] == VEHICLES
    declared = {t.type_id: (t.category or category_of(t.vclass).value) for t in FLEET_TYPES}
    seen = {}
    for row in _timeseries(out):
        seen[row["vehicle_id"]] = row["category"]
    assert len(seen) == VEHICLES
    for vehicle_id, category in seen.items():
        assert category == declared[vehicle_id.rstrip("0123456789")]
    assert set(seen.values()) == {"M1", "M2", "M3", "N", "O"}


def test_warning_onsets_follow_tables_1_2_and_formula_1(library_run):
    out, summary = library_run
    events = _rows(out / "warnings.csv")
    onsets = [e for e in events if int(e["level"]) > int(e["previous_level"])]
    assert len(onsets) > 100
    for event in onsets:
        speed_kmh, level = float(event["speed_kmh"]), int(event["level"])
        v_w = warning_speed(float(event["radius_m"]), event["category"], level)
        assert float(event["warning_speed_kmh"]) == pytest.approx(v_w, abs=1e-6)
        assert speed_kmh >= v_w
        allowance_m = kmh_to_mps(speed_kmh) * (STEP_S + 0.1)  # one update period and the 0.1 s system delay
        assert float(event["distance_m"]) <= warning_distance(speed_kmh, v_w) + allowance_m + 1e-6
    levels = summary["warnings"]["by_level"]
    assert levels["level1"] + levels["level2"] == len(onsets)


@pytest.mark.sumo
def test_without_the_driver_model_vehicles_enter_curves_too_fast_and_with_it_none_does(
    library_run, fleet_routes, tmp_path
):
    _, without = library_run
    entries = without["curve_entries_above_level1_warning_speed"]
    assert entries["more_than_1_kmh_above"] > 20
    with_response = cosimulate(_config(fleet_routes, tmp_path, driver=DriverSettings()))
    assert with_response["curve_entries_above_level1_warning_speed"]["more_than_1_kmh_above"] == 0
    for entry in _rows(tmp_path / "entries.csv"):
        level1_kmh = warning_speed(float(entry["radius_m"]), entry["category"], 1)
        assert float(entry["speed_kmh"]) <= level1_kmh + 1.0
    # No warning of the compliant driver's run goes off and on again for the same curve within 2 s;
    # counted here from the warning events themselves.
    flickered, _ = _soon_again(_rows(tmp_path / "warnings.csv"), 2.0)
    assert with_response["warnings"]["flickered"] == flickered == 0


def _soon_again(events: list[dict], window_s: float) -> tuple[int, int]:
    """Warnings that came on within ``window_s`` of the same vehicle's warning going off: for the
    curve of that warning's last onset or change (flickers), and for another curve."""
    ended: dict[str, float] = {}
    curve: dict[str, str] = {}
    same = other = 0
    for event in events:
        vehicle, time_s = event["vehicle_id"], float(event["time_s"])
        if event["event"] == "end":
            ended[vehicle] = time_s
            continue
        if event["event"] == "onset" and time_s - ended.get(vehicle, -1e9) <= window_s:
            same += curve.get(vehicle) == event["curve_id"]
            other += curve.get(vehicle) != event["curve_id"]
        curve[vehicle] = event["curve_id"]
    return same, other


def test_flickers_are_counted_as_the_warning_events_show(library_run):
    out, summary = library_run
    flickered, other = _soon_again(_rows(out / "warnings.csv"), 2.0)
    assert summary["warnings"]["flickered"] == flickered
    assert summary["warnings"]["on_again_for_another_curve"] == other


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def service_url(tmp_path_factory):
    """A real service on loopback that needs a fleet's API key: its URL and the key."""
    keys_file = tmp_path_factory.mktemp("keys") / "keys.json"
    key = add_key(keys_file, "study", "query")
    server = Server([FLEET_NET], Path(":memory:"), api_keys_file=str(keys_file), update_period_s=str(STEP_S))
    yield server.url, key
    server.stop()


@pytest.mark.sumo
def test_service_mode_gives_identical_warnings(library_run, fleet_routes, service_url, tmp_path):
    out, _ = library_run
    url, key = service_url
    summary = cosimulate(_config(fleet_routes, tmp_path, service_url=url, service_api_key=key))
    assert summary["mode"] == "service" and summary["vehicles_evaluated"] == VEHICLES
    for name in ("timeseries/part-00000.parquet", "warnings.csv", "entries.csv"):
        assert (tmp_path / name).read_bytes() == (out / name).read_bytes(), name


@pytest.mark.sumo
def test_service_mode_without_the_key_stops_on_the_services_refusal(fleet_routes, service_url, tmp_path):
    url, _ = service_url
    with pytest.raises(ServiceError, match="HTTP 401"):
        cosimulate(_config(fleet_routes, tmp_path, service_url=url))
    assert json.loads((tmp_path / "summary.json").read_text())["status"].startswith("service failed")


def _assert_complete_csv(path: Path, columns) -> int:
    text = path.read_text()
    assert text.endswith("\n")
    rows = list(csv.reader(text.splitlines()))
    assert tuple(rows[0]) == tuple(columns)
    assert all(len(row) == len(columns) for row in rows)
    return len(rows) - 1


def _start(tmp_path: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        # Every step kept (not the default one a second): the files grow fast enough to stop the run in them.
        [
            sys.executable,
            "-m",
            "csws",
            "cosim",
            "--out",
            str(tmp_path),
            "--vehicles",
            str(VEHICLES),
            "--timeseries-every",
            "1",
            *extra,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _without_progress(stderr: str) -> list[str]:
    """The lines of stderr that are not progress lines (``csws cosim: ...``)."""
    return [line for line in stderr.strip().splitlines() if not line.startswith("csws cosim: ")]


def _wait_for_rows(path: Path, process: subprocess.Popen, size: int = 200_000) -> None:
    deadline = time.monotonic() + 120
    while not (path.is_file() and path.stat().st_size > size):
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="finds SUMO's process through /proc")
def test_killed_sumo_leaves_valid_files_and_one_error_line(tmp_path):
    process = _start(tmp_path, "--traci", "--timeseries", "csv")
    _wait_for_rows(tmp_path / "timeseries.csv", process)
    sumo = _children(process.pid)
    assert sumo
    for pid in sumo:
        os.kill(pid, signal.SIGKILL)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 1
    lines = _without_progress(stderr)
    assert len(lines) == 1 and lines[0].startswith("csws: error: SUMO stopped")
    assert _assert_complete_csv(tmp_path / "timeseries.csv", TIMESERIES_COLUMNS) > 0
    _assert_complete_csv(tmp_path / "warnings.csv", EVENT_COLUMNS)
    _assert_complete_csv(tmp_path / "entries.csv", ENTRY_COLUMNS)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["complete"] is False and summary["status"].startswith("SUMO stopped")
    assert (tmp_path / "summary.png").is_file()
    assert "| status | SUMO stopped: " in (tmp_path / "summary.md").read_text()


@pytest.mark.slow
@pytest.mark.sumo
def test_an_interrupted_run_keeps_valid_files(tmp_path):
    process = _start(tmp_path, "--timeseries", "csv", "--fcd", str(tmp_path / "fcd.xml"))
    _wait_for_rows(tmp_path / "timeseries.csv", process)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130 and _without_progress(stderr) == ["csws: interrupted"]
    assert _assert_complete_csv(tmp_path / "timeseries.csv", TIMESERIES_COLUMNS) > 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    _assert_summary_of_the_interrupted_run(tmp_path, summary, stdout)
    # The FCD export is closed and parses; its last timestep is the last step's (SUMO's time: one step earlier).
    timesteps = ElementTree.parse(tmp_path / "fcd.xml").getroot().findall("timestep")
    assert float(timesteps[-1].get("time")) == pytest.approx(summary["simulated_until_s"] - 0.1, abs=1e-6)


def _assert_summary_of_the_interrupted_run(out: Path, summary: dict, stdout: str) -> None:
    """summary.png and summary.md are written for the steps the interrupted run made, and say it was interrupted."""
    assert (out / "summary.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    table = {
        cells[0]: cells[1:]
        for line in (out / "summary.md").read_text().splitlines()
        if line.startswith("| ")
        for cells in [[cell.strip() for cell in line.strip("|").split("|")]]
    }
    assert table["status"] == ["interrupted"]
    assert float(table["simulated until, s"][0]) == pytest.approx(summary["simulated_until_s"], abs=0.05)
    assert int(table["level-1 warnings"][0]) == summary["warnings"]["by_level"]["level1"]
    assert int(table["curve-part entries at or above the level-1 warning speed"][0]) == len(_rows(out / "entries.csv"))
    assert f"summary plot in {out / 'summary.png'}" in stdout


@pytest.mark.slow
@pytest.mark.sumo
def test_a_killed_run_leaves_files_that_end_at_a_complete_row(tmp_path):
    process = _start(tmp_path, "--timeseries", "csv")
    _wait_for_rows(tmp_path / "timeseries.csv", process)
    process.kill()
    process.wait(timeout=30)
    assert _assert_complete_csv(tmp_path / "timeseries.csv", TIMESERIES_COLUMNS) > 0
    _assert_complete_csv(tmp_path / "warnings.csv", EVENT_COLUMNS)


@pytest.mark.slow
@pytest.mark.sumo
def test_an_interrupted_parquet_run_writes_what_it_gathered_as_whole_parts(tmp_path):
    """Ctrl-C during a run with the Parquet time series: the rows gathered so far are written
    as a last part, every part in the folder reads, and the time series ends at the last
    step the summary counts: the signal is held until the step under way is recorded."""
    process = _start(tmp_path)
    _wait_for_rows(tmp_path / "warnings.csv", process, size=2_000)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130 and _without_progress(stderr) == ["csws: interrupted"]
    assert not list((tmp_path / "timeseries").glob("*.partial"))
    table = pq.read_table(tmp_path / "timeseries")
    assert table.schema == TIMESERIES_SCHEMA and table.num_rows > 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    last_s = max(table.column("time_s").to_pylist())
    assert last_s == pytest.approx(summary["simulated_until_s"], abs=1e-9)
    _assert_summary_of_the_interrupted_run(tmp_path, summary, stdout)


@pytest.mark.sumo
def test_the_time_series_kept_every_nth_step_or_not_at_all(library_run, fleet_routes, tmp_path):
    """``--timeseries-every 5`` keeps every fifth step's rows as the full run wrote them, in
    CSV the same values as in Parquet; ``none`` keeps no time series and the same warnings."""
    out, _ = library_run
    every = _timeseries(out)
    times = sorted({row["time_s"] for row in every})
    cosimulate(_config(fleet_routes, tmp_path / "fifth", timeseries="csv", timeseries_every=5))
    kept = _rows(tmp_path / "fifth" / "timeseries.csv")
    assert sorted({float(row["time_s"]) for row in kept}) == times[::5]
    full = {(row["time_s"], row["vehicle_id"]): row for row in every}
    for row in kept:
        original = full[(float(row["time_s"]), row["vehicle_id"])]
        assert row["lane_id"] == original["lane_id"] and float(row["speed_kmh"]) == original["speed_kmh"]
        assert int(row["level"]) == original["level"]
    cosimulate(_config(fleet_routes, tmp_path / "none", timeseries="none"))
    assert not (tmp_path / "none" / "timeseries").exists() and not (tmp_path / "none" / "timeseries.csv").exists()
    assert (tmp_path / "none" / "warnings.csv").read_bytes() == (out / "warnings.csv").read_bytes()


def test_bad_scenario_is_one_error_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "csws", "cosim", "--out", str(tmp_path), "--sumocfg", str(tmp_path / "none.sumocfg")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.strip() == f"csws: error: no such SUMO configuration: {tmp_path / 'none.sumocfg'}"
