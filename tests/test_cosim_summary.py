"""``csws cosim`` writes ``summary.png`` and ``summary.md``: real runs of the bundled fleet, their figures
checked against the run's own files by independent means (distance along the recorded positions,
counts of the CSV rows)."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pyarrow.parquet as pq
import pytest
from markers import marks_its_tests

from csws.cosim.run import CosimConfig, bundled_scenario, cosimulate
from csws.cosim.summary import run_figures

END_S = "60"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
@marks_its_tests("slow", "sumo")
def compared(tmp_path_factory) -> Path:
    """``csws cosim --driver-response`` over the first minute of the bundled fleet, every step kept."""
    out = tmp_path_factory.mktemp("cosim")
    subprocess.run(
        [
            *(sys.executable, "-m", "csws", "cosim", "--driver-response", "--end", END_S, "--out", str(out)),
            *("--fcd", str(out / "fcd.xml"), "--timeseries-every", "1"),
        ],
        check=True,
        capture_output=True,
    )
    return out


def _table(markdown: str) -> dict[str, list[str]]:
    """The rows of summary.md's table, by name."""
    return {
        cells[0]: cells[1:]
        for line in markdown.splitlines()
        if line.startswith("| ")
        for cells in [[c.strip() for c in line.strip("|").split("|")]]
    }


def _path_km(folder: Path) -> float:
    """Distance driven, km, along each vehicle's recorded positions (not its speeds)."""
    table = pq.read_table(folder / "timeseries", columns=["vehicle_id", "time_s", "x_m", "y_m"])
    rows = table.sort_by([("vehicle_id", "ascending"), ("time_s", "ascending")]).to_pydict()
    vehicle = np.array(rows["vehicle_id"])
    xy = np.column_stack([rows["x_m"], rows["y_m"]])
    steps_m = np.hypot(*np.diff(xy, axis=0).T)
    return float(steps_m[vehicle[1:] == vehicle[:-1]].sum() / 1000.0)


def test_the_summary_compares_both_runs_with_the_runs_own_figures(compared) -> None:
    assert (compared / "summary.png").read_bytes().startswith(PNG_SIGNATURE)
    table = _table((compared / "summary.md").read_text())
    assert table["run"] == ["without driver response", "with driver response"]
    for column, folder in enumerate([compared / "without_response", compared / "with_response"]):
        with open(folder / "warnings.csv", newline="") as file:
            events = list(csv.DictReader(file))
        with open(folder / "entries.csv", newline="") as file:
            entries = list(csv.DictReader(file))
        # A warning of a level is counted when a vehicle's level rises to it.
        levels = [(int(e["level"]), int(e["previous_level"])) for e in events]
        rises = {level: sum(1 for now, before in levels if now == level > before) for level in (1, 2)}
        vehicle_km = float(table["vehicle-km"][column])
        assert vehicle_km == pytest.approx(_path_km(folder), rel=0.02)
        assert int(table["level-1 warnings"][column]) == rises[1] > 0
        assert int(table["level-2 warnings"][column]) == rises[2]
        assert float(table["level-1 warnings per 100 vehicle-km"][column]) == pytest.approx(
            100.0 * rises[1] / vehicle_km, rel=1e-3, abs=0.01
        )
        assert int(table["curve-part entries at or above the level-1 warning speed"][column]) == len(entries)
    more_than_1 = [int(n) for n in table["of them more than 1 km/h above"]]
    assert more_than_1[0] > 0 and more_than_1[1] == 0  # the driver response keeps every entry near V_w


def test_each_run_of_the_comparison_has_its_own_fcd_export(compared) -> None:
    """``--fcd out/fcd.xml`` with ``--driver-response``: one file per run, each ending at that run's last step."""
    assert not (compared / "fcd.xml").exists()
    for run in ("without_response", "with_response"):
        timesteps = ElementTree.parse(compared / f"fcd.{run}.xml").getroot().findall("timestep")
        simulated_s = json.loads((compared / run / "summary.json").read_text())["simulated_until_s"]
        assert float(timesteps[-1].get("time")) == pytest.approx(simulated_s - 0.1, abs=1e-6)


@pytest.mark.sumo
def test_a_csv_time_series_gives_the_figures_of_parquet(tmp_path) -> None:
    config = CosimConfig(bundled_scenario(), tmp_path / "csv", end_s=30.0, timeseries="csv")
    cosimulate(config)
    cosimulate(CosimConfig(bundled_scenario(), tmp_path / "parquet", end_s=30.0))
    from_csv, from_parquet = run_figures(tmp_path / "csv"), run_figures(tmp_path / "parquet")
    assert from_csv.vehicle_km == pytest.approx(from_parquet.vehicle_km, rel=1e-12)
    assert len(from_csv.warned_tracks) == len(from_parquet.warned_tracks) > 0


@pytest.mark.sumo
def test_without_a_time_series_the_summary_says_what_it_lacks(tmp_path) -> None:
    subprocess.run(
        [sys.executable, "-m", "csws", "cosim", "--end", "20", "--timeseries", "none", "--out", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    table = _table((tmp_path / "summary.md").read_text())
    assert table["vehicle-km"] == ["n/a (no time series)"]
    assert table["status"] == ["complete"] and float(table["simulated until, s"][0]) == pytest.approx(20.0)
    assert re.fullmatch(r"\d+", table["level-1 warnings"][0])
    assert (tmp_path / "summary.png").read_bytes().startswith(PNG_SIGNATURE)


@pytest.mark.sumo
def test_the_drawn_warnings_are_those_of_the_first_vehicles_warned(tmp_path, monkeypatch) -> None:
    """With room for one vehicle, the plot draws the vehicle warned first, whatever its id."""
    cosimulate(CosimConfig(bundled_scenario(), tmp_path, end_s=60.0))
    rows = pq.read_table(tmp_path / "timeseries").to_pylist()
    warned = sorted((row["time_s"], row["vehicle_id"]) for row in rows if row["target_distance_m"] is not None)
    first_time_s, first_vehicle = warned[0]
    assert len({vehicle for _, vehicle in warned}) > 1 and first_vehicle != min(v for _, v in warned)
    monkeypatch.setattr("csws.cosim.summary.MAX_DRAWN_VEHICLES", 1)
    tracks = run_figures(tmp_path).warned_tracks
    first_row = next(row for row in rows if row["vehicle_id"] == first_vehicle and row["time_s"] == first_time_s)
    assert tuple(tracks[0][0]) == (first_row["target_distance_m"], first_row["speed_kmh"])
    drawn = {tuple(point) for track in tracks for point in track}
    assert drawn <= {(row["target_distance_m"], row["speed_kmh"]) for row in rows if row["vehicle_id"] == first_vehicle}
