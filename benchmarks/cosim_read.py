"""How a scheduled co-simulation reads the vehicles that are due, as the due set shrinks: getters against
subscriptions.

A scheduled run (``csws cosim --evaluate scheduled``) reads at each step only the vehicles that are due, a
share of the fleet (44 % and 39 % of the vehicle-steps on the fleet road in the last full run); it reads
each of them by four getter calls (lane, lane position, speed, route id; :class:`csws.cosim.sumo.Simulation`).
The same values can come from SUMO's subscriptions instead:

* ``getters``: what the run does; four getter calls per due vehicle.
* ``subscribe_all``: every vehicle subscribed to the four values once, when it departs; one
  ``getAllSubscriptionResults`` a step, the due vehicles picked from it.
* ``subscribe_due``: only the due vehicles subscribed: those that fall due are subscribed, those that fall
  asleep unsubscribed, each step; one ``getAllSubscriptionResults`` a step.
* ``context``: one context subscription of a junction at the road's middle, reaching the whole road: every
  vehicle's four values with no call per vehicle at all; the due ones picked from it.

Each run is the fleet road of :mod:`benchmarks.cosim` (1,000 vehicles placed at the start, 30 s at 0.1 s)
in a process of its own; the due set is drawn at random with the share asked for, a hundredth of the fleet
drawn again each step (a schedule's vehicles wake and fall asleep a few at a time). The figure is the CPU time of
a step with its read, SUMO's step included (libsumo's SUMO runs in the process, and subscriptions make it
build their results within its step), against the getters' at the same share (and bare SUMO's) in the same
run, each the least of three rounds that run every configuration in turn.

Run with ``python -m benchmarks.cosim_read``.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.command import arguments
from benchmarks.cosim import DURATION_S, STEP_S, VEHICLES, _fleet_scenario, _in_own_process
from benchmarks.rows import Row, context
from csws.cosim.run import Scenario
from csws.cosim.sumo import sumo_arguments
from csws.sumo.binaries import sumo_binary, sumo_home

#: The ways of reading compared, and the shares of the fleet due at a step.
METHODS = ("getters", "subscribe_all", "subscribe_due", "context")
DUE_SHARES = (1.0, 0.44, 0.2, 0.05)
#: libsumo's variable ids of the four values read: lane, lane position, speed, route id.
_VARIABLES = (0x51, 0x56, 0x40, 0x53)
#: A hundredth of the fleet is drawn again each step (a vehicle stays due, or asleep, some 10 s on average).
REDRAWN_SHARE = 0.01
#: Rounds of every configuration; each figure is the least of its rounds.
ROUNDS = 3


def _read_run(scenario: Scenario, method: str, due_share: float, duration_s: float, seed: int = 1) -> dict:
    """Step the scenario, reading the due vehicles by ``method`` ("bare": no read); CPU ms a step (own process:
    SUMO runs in it, so its CPU time is SUMO's and the read's, whatever else the machine runs)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    rng = np.random.default_rng(seed)
    libsumo.start(
        [str(sumo_binary("sumo")), *sumo_arguments(None, scenario.net, scenario.routes, STEP_S, 0, duration_s)]
    )
    due: dict[str, bool] = {}
    subscribed: set[str] = set()
    if method == "context":
        middle = sorted(libsumo.junction.getIDList())[len(libsumo.junction.getIDList()) // 2]
        libsumo.junction.subscribeContext(middle, 0xA4, 1e5, list(_VARIABLES))
    read = 0
    started = time.process_time()
    steps = 0
    while libsumo.simulation.getMinExpectedNumber() > 0 and libsumo.simulation.getTime() < duration_s - 1e-9:
        libsumo.simulationStep()
        steps += 1
        for vehicle_id in libsumo.simulation.getDepartedIDList():
            due[vehicle_id] = bool(rng.random() < due_share)
            if method == "subscribe_all":
                libsumo.vehicle.subscribe(vehicle_id, _VARIABLES)
        for vehicle_id in libsumo.simulation.getArrivedIDList():
            due.pop(vehicle_id, None)
            subscribed.discard(vehicle_id)
        ids = list(due)
        for k in np.flatnonzero(rng.random(len(ids)) < REDRAWN_SHARE).tolist():
            due[ids[k]] = bool(rng.random() < due_share)
        due_ids = [vehicle_id for vehicle_id, is_due in due.items() if is_due]
        read += len(_read(libsumo, method, due_ids, subscribed))
    seconds = time.process_time() - started
    libsumo.close()
    return {"ms_per_step": round(seconds / steps * 1e3, 3), "vehicles_read_per_step": round(read / steps, 1)}


def _read(libsumo, method: str, due_ids: list[str], subscribed: set[str]) -> list[tuple]:
    """The four values of each due vehicle, read by ``method``."""
    vehicle = libsumo.vehicle
    if method == "bare":
        return []
    if method == "getters":
        getters = (vehicle.getLaneID, vehicle.getLanePosition, vehicle.getSpeed, vehicle.getRouteID)
        columns = [list(map(getter, due_ids)) for getter in getters]
        return list(zip(*columns, strict=True))
    if method == "subscribe_due":
        wanted = set(due_ids)
        for vehicle_id in wanted - subscribed:
            vehicle.subscribe(vehicle_id, _VARIABLES)
        for vehicle_id in subscribed - wanted:
            vehicle.unsubscribe(vehicle_id)
        subscribed.clear()
        subscribed.update(wanted)
        results = vehicle.getAllSubscriptionResults()
    elif method == "subscribe_all":
        results = vehicle.getAllSubscriptionResults()
    else:
        results = next(iter(libsumo.junction.getAllContextSubscriptionResults().values()), {})
    return [tuple(results[vehicle_id][variable] for variable in _VARIABLES) for vehicle_id in due_ids]


def run(vehicles: int = VEHICLES, duration_s: float = DURATION_S, rounds: int = ROUNDS) -> dict:
    """ms a step of each method at each due share, and bare SUMO's, each in a process of its own: the least of
    ``rounds`` rounds, each running every configuration once (so that all see the same machine load)."""
    keys = [("bare", 0.0)] + [(method, share) for share in DUE_SHARES for method in METHODS]
    best: dict[tuple[str, float], dict] = {}
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-read-") as folder:
        scenario = _fleet_scenario(Path(folder), vehicles)
        for _round in range(rounds):
            for method, share in keys:
                measured = _in_own_process(_read_run, scenario, method, share, duration_s)
                if (method, share) not in best or measured["ms_per_step"] < best[(method, share)]["ms_per_step"]:
                    best[(method, share)] = measured
    bare = best[("bare", 0.0)]["ms_per_step"]
    figures: dict = {"vehicles": vehicles, "bare_ms_per_step": bare, "load_average": os.getloadavg()[0]}
    for (method, share), measured in best.items():
        if method != "bare":
            figures[f"{method}@{share:g}"] = measured | {"ratio": round(measured["ms_per_step"] / bare, 3)}
    return figures


def _against_getters(figures: dict, share: float) -> dict[str, float]:
    """Each method's step and read at ``share`` against the getters' (the run's way) at the same share."""
    getters_ms = figures[f"getters@{share:g}"]["ms_per_step"]
    return {method: figures[f"{method}@{share:g}"]["ms_per_step"] / getters_ms for method in METHODS}


def rows(figures: dict) -> list[Row]:
    """Each due share's four ways of reading, step and read against the getters' (the run's way), the least named."""
    table = []
    for share in DUE_SHARES:
        ratios = _against_getters(figures, share)
        least = min(ratios, key=ratios.__getitem__)
        getters = figures[f"getters@{share:g}"]
        table.append(
            context(
                f"cosim read: {share:.0%} of {figures['vehicles']:,} vehicles due, step and read (x getters)",
                " / ".join(f"{ratio:.3g}" for ratio in ratios.values()),
                f"{' / '.join(METHODS)}; least: {least}; getters {getters['ms_per_step']:.2f} CPU ms/step "
                f"({getters['ratio']:.2f} x bare SUMO's {figures['bare_ms_per_step']:.2f})",
            )
        )
    return table


def main() -> None:
    """Print each method's step with its read against the getters', by due share."""
    arguments("benchmarks.cosim_read", __doc__)
    figures = run()
    print(f"{figures['vehicles']} vehicles; bare SUMO {figures['bare_ms_per_step']:.2f} CPU ms/step")
    print(f"{'due share':>9}  {'getters ms':>10}  " + "  ".join(f"{method:>14}" for method in METHODS))
    for share in DUE_SHARES:
        ratios = _against_getters(figures, share)
        getters_ms = figures[f"getters@{share:g}"]["ms_per_step"]
        print(f"{share:>9g}  {getters_ms:>10.2f}  " + "  ".join(f"{ratio:>13.3f}x" for ratio in ratios.values()))
    print(f"(step and read against the getters' at the same share; load average {figures['load_average']:.1f})")


if __name__ == "__main__":
    main()
