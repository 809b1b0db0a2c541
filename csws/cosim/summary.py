"""A co-simulation's result at a glance: ``summary.png`` and ``summary.md`` beside its files.

Read back from what the runs wrote (:mod:`csws.cosim.records`), one run or the two runs of
``--driver-response`` (without and with the driver's response):

* **speed against distance to the curve**: every warned vehicle's speed while it is warned,
  against its distance to the target CPOI (3.12; the start of the curve part it is warned
  for), from the time series;
* **excess speed at curve entry**: how far above the part's level-1 warning speed vehicles
  entered curve parts (``entries.csv``), as a distribution per run;
* **warnings per 100 vehicle-km**: warning onsets of each level (``summary.json``) per 100 km
  driven by the evaluated vehicles, the distance integrated from the time series' speeds
  (trapezoids between a vehicle's recorded steps).

A run kept without a time series (``--timeseries none``) has no speeds to plot and no distance
to divide by: the summary says so instead.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

__all__ = ["RunFigures", "run_figures", "write_run_summary"]

#: The time series' columns the summary reads.
_COLUMNS = ["time_s", "vehicle_id", "speed_kmh", "target_distance_m"]
#: At most this many warned vehicles are drawn in the speed panel (the first ones warned), so it stays legible.
MAX_DRAWN_VEHICLES = 300
#: Colour of each run in every panel, in the order the runs are given.
_RUN_COLOURS = ("#d62728", "#1f77b4")


@dataclass
class RunFigures:
    """What the summary shows of one run.

    Attributes
    ----------
    warnings_by_level
        Warning onsets of level 1 and 2 (``summary.json``).
    entry_excess_kmh
        Excess over the level-1 warning speed of every curve-part entry at or above it, km/h.
    vehicle_km
        Distance driven by the evaluated vehicles, km; None without a time series.
    warned_tracks
        Per warning of the first :data:`MAX_DRAWN_VEHICLES` vehicles warned: distance to its
        target, m, and speed, km/h, at each recorded step of it, ``(k, 2)``.
    status
        How the run ended (``summary.json``: ``complete``, ``interrupted``, ``SUMO stopped: ...``).
    simulated_until_s
        The simulation time of its last step, s.
    """

    warnings_by_level: dict[int, int]
    entry_excess_kmh: np.ndarray
    vehicle_km: float | None
    warned_tracks: list[np.ndarray]
    status: str = "complete"
    simulated_until_s: float = 0.0

    def per_100_vehicle_km(self, level: int) -> float | None:
        """Warning onsets of ``level`` per 100 vehicle-km; None without a distance."""
        if not self.vehicle_km:
            return None
        return 100.0 * self.warnings_by_level[level] / self.vehicle_km


def _timeseries(folder: Path) -> pa.Table | None:
    """The run's time series (the columns the summary needs), None when it kept none."""
    if (folder / "timeseries").is_dir():
        return pq.read_table(folder / "timeseries", columns=_COLUMNS)
    if (folder / "timeseries.csv").is_file():
        options = pa_csv.ConvertOptions(
            include_columns=_COLUMNS, column_types={"vehicle_id": pa.string(), "target_distance_m": pa.float64()}
        )
        return pa_csv.read_csv(folder / "timeseries.csv", convert_options=options)
    return None


def _vehicle_km(vehicle: np.ndarray, time_s: np.ndarray, speed_kmh: np.ndarray) -> float:
    """Distance driven, km: speed integrated over time by trapezoids between each vehicle's consecutive rows
    (rows sorted by vehicle, then time)."""
    same = vehicle[1:] == vehicle[:-1]
    step_h = np.diff(time_s) / 3600.0
    return float(np.sum(np.where(same, 0.5 * (speed_kmh[1:] + speed_kmh[:-1]) * step_h, 0.0)))


def _warned_tracks(
    vehicle: np.ndarray, time_s: np.ndarray, distance_m: np.ndarray, speed_kmh: np.ndarray
) -> list[np.ndarray]:
    """Distance to target and speed along each warning of the first :data:`MAX_DRAWN_VEHICLES` vehicles
    warned, in the order of their first warning (rows sorted by vehicle, then time): a warning's track
    ends where the vehicle's warning does or its distance to the target grows (a new target)."""
    rows = np.flatnonzero(~np.isnan(distance_m))
    if not rows.size:
        return []
    codes, first = np.unique(vehicle[rows], return_index=True)
    earliest = codes[np.lexsort((codes, time_s[rows[first]]))][:MAX_DRAWN_VEHICLES]
    rows = rows[np.isin(vehicle[rows], earliest)]
    breaks = (np.diff(rows) != 1) | (vehicle[rows[1:]] != vehicle[rows[:-1]]) | (np.diff(distance_m[rows]) > 0.0)
    points = np.column_stack([distance_m[rows], speed_kmh[rows]])
    return np.split(points, np.flatnonzero(breaks) + 1)


def run_figures(folder: Path) -> RunFigures:
    """What the summary shows of the run written into ``folder``.

    Raises
    ------
    OSError
        When its ``summary.json`` or ``entries.csv`` cannot be read.
    """
    summary = json.loads((folder / "summary.json").read_text("utf-8"))
    by_level = summary["warnings"]["by_level"]
    with open(folder / "entries.csv", newline="", encoding="utf-8") as file:
        excess_kmh = np.array([float(row["excess_kmh"]) for row in csv.DictReader(file)])
    table = _timeseries(folder)
    vehicle_km, tracks = None, []
    if table is not None and table.num_rows:
        table = table.sort_by([("vehicle_id", "ascending"), ("time_s", "ascending")])
        vehicle = pc.dictionary_encode(table["vehicle_id"]).combine_chunks().indices.to_numpy()
        time_s = table["time_s"].to_numpy()
        speed_kmh = table["speed_kmh"].to_numpy()
        distance_m = table["target_distance_m"].fill_null(np.nan).to_numpy()
        vehicle_km = _vehicle_km(vehicle, time_s, speed_kmh)
        tracks = _warned_tracks(vehicle, time_s, distance_m, speed_kmh)
    return RunFigures(
        {1: by_level["level1"], 2: by_level["level2"]},
        excess_kmh,
        vehicle_km,
        tracks,
        summary["status"],
        summary["simulated_until_s"],
    )


def _plot(runs: Mapping[str, RunFigures], path: Path) -> None:
    """The three panels, one colour per run."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot
    from matplotlib.collections import LineCollection

    figure, (speeds, excess, rates) = pyplot.subplots(1, 3, figsize=(16, 4.8))
    for (label, run), colour in zip(runs.items(), _RUN_COLOURS, strict=False):
        if run.warned_tracks:
            speeds.add_collection(
                LineCollection(run.warned_tracks, colors=colour, linewidths=0.6, alpha=0.35, label=label)
            )
    speeds.autoscale()
    speeds.invert_xaxis()
    speeds.set(
        xlabel="distance to the target curve point, m",
        ylabel="speed, km/h",
        title="warned vehicles: speed approaching the curve",
    )
    if not any(run.warned_tracks for run in runs.values()):
        speeds.text(0.5, 0.5, "no time series kept, or nobody warned", ha="center", transform=speeds.transAxes)
    all_excess = np.concatenate([run.entry_excess_kmh for run in runs.values()] + [np.zeros(1)])
    bins = np.linspace(min(0.0, float(all_excess.min())), max(1.0, float(all_excess.max())), 40)
    for (label, run), colour in zip(runs.items(), _RUN_COLOURS, strict=False):
        excess.hist(
            run.entry_excess_kmh,
            bins=bins,
            color=colour,
            alpha=0.55,
            label=f"{label}: {run.entry_excess_kmh.size} entries",
        )
    excess.axvline(0.0, color="black", linewidth=0.8)
    excess.set(
        xlabel="speed above the level-1 warning speed at curve entry, km/h",
        ylabel="curve-part entries",
        title="excess speed at curve entry",
    )
    width = 0.8 / len(runs)
    for offset, ((label, run), colour) in enumerate(zip(runs.items(), _RUN_COLOURS, strict=False)):
        values = [run.per_100_vehicle_km(level) or 0.0 for level in (1, 2)]
        rates.bar(np.arange(2) + offset * width, values, width, color=colour, label=label)
    rates.set_xticks(np.arange(2) + width * (len(runs) - 1) / 2, ["level 1", "level 2"])
    rates.set(ylabel="warnings per 100 vehicle-km", title="warnings per 100 vehicle-km")
    for axes in (speeds, excess, rates):
        axes.grid(alpha=0.3)
        if (len(runs) > 1 or axes is excess) and axes.get_legend_handles_labels()[0]:
            axes.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    pyplot.close(figure)


def _markdown(runs: Mapping[str, RunFigures]) -> str:
    """The figures of each run as a table, and the plot."""

    def number(value: float | None, digits: int = 1) -> str:
        return "n/a (no time series)" if value is None else f"{value:.{digits}f}"

    lines = [
        "# Co-simulation summary",
        "",
        "![summary](summary.png)",
        "",
        "| run | " + " | ".join(runs) + " |",
        "|---|" + "---|" * len(runs),
    ]
    rows = {
        "status": [run.status for run in runs.values()],
        "simulated until, s": [number(run.simulated_until_s) for run in runs.values()],
        "vehicle-km": [number(run.vehicle_km) for run in runs.values()],
        "level-1 warnings": [str(run.warnings_by_level[1]) for run in runs.values()],
        "level-2 warnings": [str(run.warnings_by_level[2]) for run in runs.values()],
        "level-1 warnings per 100 vehicle-km": [number(run.per_100_vehicle_km(1), 2) for run in runs.values()],
        "level-2 warnings per 100 vehicle-km": [number(run.per_100_vehicle_km(2), 2) for run in runs.values()],
        "curve-part entries at or above the level-1 warning speed": [
            str(run.entry_excess_kmh.size) for run in runs.values()
        ],
        "of them more than 1 km/h above": [str(int((run.entry_excess_kmh > 1.0).sum())) for run in runs.values()],
        "median excess at entry, km/h": [
            number(float(np.median(run.entry_excess_kmh)) if run.entry_excess_kmh.size else 0.0)
            for run in runs.values()
        ],
    }
    lines += [f"| {name} | " + " | ".join(values) + " |" for name, values in rows.items()]
    return "\n".join(lines) + "\n"


def write_run_summary(folders: Mapping[str, Path], out: Path) -> dict[str, RunFigures]:
    """Write ``summary.png`` and ``summary.md`` into ``out`` from the runs in ``folders`` (by label).

    Raises
    ------
    OSError
        When a run's files cannot be read or the summary cannot be written.
    """
    runs = {label: run_figures(folder) for label, folder in folders.items()}
    _plot(runs, out / "summary.png")
    (out / "summary.md").write_text(_markdown(runs), encoding="utf-8")
    return runs
