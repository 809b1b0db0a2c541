"""The ``csws cosim`` subcommand: its arguments; the work is in ``csws.cosim.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred
from csws.cli.argtypes import comma_list, key_file, one_of, output_folder, positive_float, positive_int, step_length

from .records import TIMESERIES_FORMATS

#: The warning systems a co-simulation can evaluate (``--systems``).
SYSTEMS = ("csws", "fcw")
#: How a co-simulation chooses the vehicles it evaluates (``--evaluate``, :mod:`csws.cosim.schedule`).
EVALUATION_MODES = ("scheduled", "every-step")


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws cosim``."""
    parser = commands.add_parser(
        "cosim",
        help="co-simulate a fleet in SUMO and record who was warned where",
        description="Drive a SUMO scenario (default: the bundled mixed fleet on the fleet network) and evaluate "
        "each vehicle where a warning can arise, in this process or over HTTP against a csws service. Writes "
        "the time series (timeseries/*.parquet or timeseries.csv, one step per simulated second), warnings.csv, "
        "entries.csv (curve parts entered at or above the level-1 warning speed) and summary.json into --out "
        "as the run goes (with lon/lat on a geo-referenced network), and summary.png and summary.md when it "
        "ends, also when interrupted.",
    )
    scenario = parser.add_argument_group("scenario (default: the bundled fleet, networks/fleet_scenario/fleet.sumocfg)")
    scenario.add_argument("--sumocfg", type=Path, default=None, help="a SUMO configuration")
    scenario.add_argument("--net", type=Path, default=None, help="a SUMO network (with --routes)")
    scenario.add_argument(
        "--routes", type=comma_list(Path, "route file"), default=None, help="route files, comma-separated"
    )
    scenario.add_argument(
        "--vehicles",
        type=positive_int,
        default=None,
        help="generate a mixed fleet of this many vehicles (one per second) on the fleet network",
    )
    parser.add_argument(
        "--out", type=output_folder, default=Path("cosim-out"), help="output folder (default: cosim-out)"
    )
    parser.add_argument("--step-length", type=step_length, default=0.1, help="SUMO step length in s (default 0.1)")
    parser.add_argument("--end", type=positive_float, default=None, help="stop at this simulation time, s")
    parser.add_argument(
        "--systems",
        type=comma_list(one_of(SYSTEMS), "system"),
        default=["csws"],
        help="warning systems to evaluate, comma-separated: csws (curve speed warning, the default), "
        "fcw (forward collision warning, docs/fcw.md), or csws,fcw",
    )
    parser.add_argument(
        "--service",
        default=None,
        metavar="URL",
        help="ask a running csws service (POST /v1/warnings) instead of the library, e.g. http://127.0.0.1:8000",
    )
    parser.add_argument(
        "--api-key-file",
        type=key_file,
        default=None,
        metavar="FILE",
        dest="api_key",
        help="with --service: the fleet's API key (csws keys add), on the first line of FILE "
        "(default: the CSWS_API_KEY environment variable, if set)",
    )
    interface = parser.add_mutually_exclusive_group()
    interface.add_argument(
        "--traci", action="store_true", help="run SUMO as a separate program over TraCI (default: libsumo)"
    )
    interface.add_argument("--gui", action="store_true", help="run sumo-gui over TraCI")
    parser.add_argument(
        "--driver-response",
        action="store_true",
        help="run the fleet without and with the driver-response model (react 0.8 s, brake at 4.9 m/s^2) and compare",
    )
    parser.add_argument("--seed", type=int, default=0, help="SUMO's random seed and the generated fleet's (default 0)")
    parser.add_argument(
        "--timeseries",
        choices=TIMESERIES_FORMATS,
        default="parquet",
        help="how to keep the vehicles' states: a folder of Parquet files (default), "
        "timeseries.csv, or none (warning events, entries and summary only)",
    )
    parser.add_argument(
        "--timeseries-every",
        type=positive_int,
        default=None,
        metavar="N",
        help="keep every N-th step in the time series and the FCD export (default: one step per simulated "
        "second, every 10th at 0.1 s steps; 1 keeps every step, which reads every vehicle at every step)",
    )
    parser.add_argument(
        "--fcd",
        type=Path,
        default=None,
        metavar="FILE",
        help="also write the run as SUMO's FCD export (<fcd-export><timestep><vehicle id x y angle type speed "
        "pos lane .../>) with each vehicle's warning level, at the steps the time series keeps",
    )
    parser.add_argument(
        "--evaluate",
        choices=EVALUATION_MODES,
        default="scheduled",
        help="scheduled (default): evaluate a vehicle only from where a curve warning can arise or another "
        "vehicle can come within its forward collision warning's range, with the same warnings and entries as "
        "every-step (every vehicle at every step); --service is evaluated every step, and each step the time "
        "series keeps reads every vehicle",
    )
    parser.set_defaults(handler=deferred("csws.cosim.run"))
