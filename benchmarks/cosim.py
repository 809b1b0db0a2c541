"""Co-simulation cost against SUMO itself: 1,000 vehicles at 0.1 s steps.

Every run is the same libsumo simulation of the fleet network built with four lanes each
way, 1,000 vehicles placed along the road at the start, 30 s, each run timed whole (SUMO's
start included) in this one process:

* ``bare``: libsumo alone, ``simulationStep()`` only: the baseline of the ratios;
* ``read only``: csws reading every vehicle each step, no evaluation, no time series: the
  least a co-simulation that looks at every vehicle costs;
* ``without evaluation``: reading and the default time series (the older baseline, kept
  for continuity);
* ``default``: evaluation with the default time series (Parquet, every step);
* ``events only``: evaluation, no time series (warning events, entries and summary).

Targets: the default run at most 1.5 times bare SUMO, the events-only run at most 1.25
times; evaluation adds at most 50 % to the run without it. The default run's summary
also gives its milliseconds per step by component (SUMO's step with the read,
evaluation, recording).

Run with ``python -m benchmarks.cosim``.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from csws.binaries import sumo_binary, sumo_home
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.cosim.sumo import sumo_arguments
from csws.networks.fleet import FLEET_TYPES, backward_edges, build_fleet_net, draw_types, forward_edges, vtype_xml

VEHICLES = 1000
STEP_S = 0.1
DURATION_S = 30.0
LANES = 4
TARGET_OVERHEAD = 0.5
TARGET_DEFAULT_RATIO = 1.5
TARGET_EVENTS_RATIO = 1.25


def _routes_xml(count: int, seed: int = 0) -> str:
    """``count`` vehicles of the fleet's mix, each starting at a random section of either direction at t = 0."""
    rng = np.random.default_rng(seed)
    directions = (forward_edges(), backward_edges())
    lines = ["<routes>", *(vtype_xml(t) for t in FLEET_TYPES)]
    for index, fleet_type in enumerate(draw_types(count, rng)):
        edges = directions[index % 2]
        first = int(rng.integers(0, len(edges) - 1))
        type_id = fleet_type.type_id
        lines.append(
            f'<vehicle id="{type_id}{index}" type="{type_id}" depart="0" departPos="random_free" departLane="random" '
            f'departSpeed="max"><route edges="{" ".join(edges[first:])}"/></vehicle>'
        )
    return "\n".join(lines + ["</routes>"]) + "\n"


def _bare_sumo_s(scenario: Scenario) -> tuple[float, int]:
    """Seconds and steps of the scenario in libsumo alone: start, ``simulationStep()`` until the end, close."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    arguments = sumo_arguments(None, scenario.net, scenario.routes, STEP_S, 0, DURATION_S)
    started = time.perf_counter()
    libsumo.start([str(sumo_binary("sumo")), *arguments])
    steps = 0
    while libsumo.simulation.getMinExpectedNumber() > 0 and libsumo.simulation.getTime() < DURATION_S - 1e-9:
        libsumo.simulationStep()
        steps += 1
    libsumo.close()
    return time.perf_counter() - started, steps


def _timed(config: CosimConfig) -> tuple[float, dict]:
    started = time.perf_counter()
    summary = cosimulate(config)
    return time.perf_counter() - started, summary


def run() -> dict:
    """Wall times of every run (ms per step), their ratios to bare SUMO, and the default
    run's milliseconds per step by component."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as work:
        work_path = Path(work)
        net = build_fleet_net(work_path / "fleet4.net.xml", lanes=LANES)
        routes = work_path / "bench.rou.xml"
        routes.write_text(_routes_xml(VEHICLES), encoding="utf-8")
        scenario = Scenario(None, net, (routes,))
        common = dict(scenario=scenario, step_length_s=STEP_S, end_s=DURATION_S)
        bare_s, bare_steps = _bare_sumo_s(scenario)
        runs = {
            "read_only": CosimConfig(out=work_path / "read", evaluate=False, timeseries="none", **common),
            "without_evaluation": CosimConfig(out=work_path / "baseline", evaluate=False, **common),
            "default": CosimConfig(out=work_path / "default", **common),
            "events_only": CosimConfig(out=work_path / "events", timeseries="none", **common),
        }
        timed = {name: _timed(config) for name, config in runs.items()}
    ms_per_step = {"bare": 1000.0 * bare_s / bare_steps}
    ms_per_step |= {name: 1000.0 * seconds / summary["steps"] for name, (seconds, summary) in timed.items()}
    default = timed["default"][1]
    return {
        "vehicles": default["vehicles_evaluated"],
        "steps": default["steps"],
        "ms_per_step": ms_per_step,
        "ratio_to_bare": {name: value / ms_per_step["bare"] for name, value in ms_per_step.items() if name != "bare"},
        "overhead": timed["default"][0] / timed["without_evaluation"][0] - 1.0,
        "default_components_ms_per_step": default["ms_per_step"],
    }


def main() -> None:
    """Print each figure beside its target."""
    figures = run()
    print(f"{figures['vehicles']} vehicles, {figures['steps']} steps of {STEP_S:g} s")
    for name, value in figures["ms_per_step"].items():
        ratio = figures["ratio_to_bare"].get(name)
        print(f"{name:<20}{value:>8.2f} ms/step" + (f"  {ratio:.2f} x bare SUMO" if ratio else ""))
    print(f"evaluation overhead {figures['overhead']:.0%} (target <= {TARGET_OVERHEAD:.0%})")
    print("default run by component, ms/step:", figures["default_components_ms_per_step"])


if __name__ == "__main__":
    main()
