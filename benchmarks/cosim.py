"""Co-simulation cost: 1,000 vehicles at 0.1 s steps, with and without warning evaluation.

Both runs are the same libsumo simulation of the fleet network built with four lanes each
way, 1,000 vehicles placed along the road at the start; both read every vehicle through
subscriptions and stream the time series. One run asks the engine for every vehicle at
every step, the other does not. Target: evaluation adds at most 50 % to the baseline.

Run with ``python -m benchmarks.cosim``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.networks.fleet import FLEET_TYPES, backward_edges, build_fleet_net, draw_types, forward_edges, vtype_xml

VEHICLES = 1000
STEP_S = 0.1
DURATION_S = 30.0
LANES = 4
TARGET_OVERHEAD = 0.5


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


def _timed(config: CosimConfig) -> tuple[float, dict]:
    started = time.perf_counter()
    summary = cosimulate(config)
    return time.perf_counter() - started, summary


def run() -> dict:
    """Wall times of the baseline and the evaluated run, and the overhead ratio."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as work:
        work_path = Path(work)
        net = build_fleet_net(work_path / "fleet4.net.xml", lanes=LANES)
        routes = work_path / "bench.rou.xml"
        routes.write_text(_routes_xml(VEHICLES), encoding="utf-8")
        scenario = Scenario(None, net, (routes,))
        common = dict(scenario=scenario, step_length_s=STEP_S, end_s=DURATION_S)
        baseline_s, baseline = _timed(CosimConfig(out=work_path / "baseline", evaluate=False, **common))
        evaluated_s, evaluated = _timed(CosimConfig(out=work_path / "evaluated", **common))
    steps = evaluated["steps"]
    return {
        "vehicles": evaluated["vehicles_evaluated"],
        "steps": steps,
        "baseline_s": baseline_s,
        "evaluated_s": evaluated_s,
        "baseline_ms_per_step": 1000 * baseline_s / baseline["steps"],
        "evaluated_ms_per_step": 1000 * evaluated_s / steps,
        "overhead": evaluated_s / baseline_s - 1,
    }


def main() -> None:
    """Print each figure beside its target."""
    figures = run()
    print(f"{figures['vehicles']} vehicles, {figures['steps']} steps of {STEP_S:g} s")
    print(f"{'figure':<34}{'value':>12}  target")
    print(f"{'baseline (no evaluation), ms/step':<34}{figures['baseline_ms_per_step']:>12.2f}  -")
    print(f"{'with evaluation, ms/step':<34}{figures['evaluated_ms_per_step']:>12.2f}  -")
    verdict = "met" if figures["overhead"] <= TARGET_OVERHEAD else "NOT met"
    print(f"{'evaluation overhead':<34}{figures['overhead']:>11.0%}  <= {TARGET_OVERHEAD:.0%} ({verdict})")


if __name__ == "__main__":
    main()
