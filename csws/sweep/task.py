"""One run of a study: one co-simulation in this process, reduced to one row of figures.

This is the function a Dask worker calls per task. The co-simulation runs with libsumo in the
worker's own process (:func:`csws.cosim.run.cosimulate`): libsumo holds one simulation per
process, so a lock keeps a worker started with several threads to one run at a time. The run's
files go to a temporary folder that is removed once its figures are read:

* ``entries.csv``: the entries into a curve part where a warning triggered, with the speed and
  the excess over the part's level-1 warning speed V_w1; an entry is *above V_w1* (V_w2) when
  the speed is above the part's V_w1 (V_w2) of Table 1 (a warning the release rule holds on
  can trigger a little below);
* ``warnings.csv``: the warnings, counted for the equipped vehicles only (the others see none);
* SUMO's trip information (``--tripinfo-output``, unfinished trips included): the vehicles,
  the distance each drove and its time loss (the time it took beyond driving at its desired
  speed: braking for a warning adds to it).

A reference run (no vehicle equipped) runs without the driver-response model: every vehicle
is still evaluated, so its entries above V_w are those of the fleet without CSWS.
"""

from __future__ import annotations

import csv
import tempfile
import threading
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

from csws.cosim.driver import DriverSettings, is_equipped
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.standard import Level, warning_speed
from csws.sumo.netbuild import required_attribute

from .study import RunSpec

__all__ = ["run_task", "scenario_files"]

#: One libsumo simulation per process at a time.
_LIBSUMO = threading.Lock()
#: Name of SUMO's trip information in a run's folder.
TRIPINFO = "tripinfo.xml"


def run_task(spec: RunSpec) -> dict[str, Any]:
    """Run ``spec`` and return its row of figures (:data:`csws.sweep.results.RUN_SCHEMA`)."""
    with _LIBSUMO, tempfile.TemporaryDirectory(prefix=f"csws-sweep-{spec.key}-") as folder:
        out = Path(folder)
        config = CosimConfig(
            scenario_files(spec, out),
            out / "cosim",
            step_length_s=spec.factors.step_length_s,
            end_s=spec.scenario.end_s,
            driver=_driver(spec),
            seed=spec.seed,
            timeseries="none",
        )
        summary = cosimulate(config)
        return _figures(spec, summary, out)


def _driver(spec: RunSpec) -> DriverSettings | None:
    """The driver-response model of the run's factors; None in a reference run (no vehicle equipped)."""
    factors = spec.factors
    if spec.reference:
        return None
    equipped_share, compliance_share = factors.equipped_share, factors.compliance_share
    reaction_s, decel_mps2 = factors.reaction_s, factors.decel_mps2
    if equipped_share is None or compliance_share is None or reaction_s is None or decel_mps2 is None:
        raise ValueError(f"run {spec.key}: a run with CSWS needs every CSWS factor, got {factors}")
    return DriverSettings(
        reaction_s=reaction_s,
        decel_mps2=decel_mps2,
        equipped_share=equipped_share,
        compliance_share=compliance_share,
        draw_seed=spec.seed,
    )


def scenario_files(spec: RunSpec, folder: Path) -> Scenario:
    """The run's SUMO configuration in ``folder``: the scenario's own with absolute input paths, the
    fleet's generated route file when the scenario is the bundled fleet, and trip information on."""
    scenario = spec.scenario
    if scenario.bundled == "fleet":
        from csws.networks.fleet import FLEET_NAME, fleet_dir, fleet_routes_xml, sumocfg_xml, types_for_mix

        mix = scenario.mix(spec.factors.category_mix)
        kinds = {} if mix is None else {"types": types_for_mix(mix)}
        routes = folder / "fleet.rou.xml"
        routes.write_text(
            fleet_routes_xml(scenario.vehicles, period_s=scenario.vehicles, seed=spec.seed, **kinds), encoding="utf-8"
        )
        source = folder / "fleet.sumocfg"
        source.write_text(sumocfg_xml(str(fleet_dir() / f"{FLEET_NAME}.net.xml"), str(routes)), encoding="utf-8")
    elif scenario.bundled == "badhersfeld":
        from csws.networks import networks_dir

        source = networks_dir() / "badhersfeld.sumocfg"
    elif scenario.sumocfg is not None:
        source = Path(scenario.sumocfg)
    else:
        raise ValueError("a scenario names a bundled network or a sumocfg")
    return _with_tripinfo(source, folder / "run.sumocfg")


def _with_tripinfo(source: Path, config: Path) -> Scenario:
    """Copy the configuration ``source`` to ``config`` with absolute input files and trip information written."""
    root = ElementTree.parse(source).getroot()
    net = None
    for element in root.iter():
        value = element.get("value")
        if value is not None and element.tag.endswith(("-file", "-files")):
            paths = [str((source.parent / part.strip()).resolve()) for part in value.split(",") if part.strip()]
            element.set("value", ",".join(paths))
            net = paths[0] if element.tag == "net-file" else net
    output = root.find("output")
    if output is None:
        output = ElementTree.SubElement(root, "output")
    ElementTree.SubElement(output, "tripinfo-output", value=str(config.parent / TRIPINFO))
    ElementTree.SubElement(output, "tripinfo-output.write-unfinished", value="true")
    if net is None:
        raise ValueError(f"{source} names no net-file")
    ElementTree.ElementTree(root).write(config, encoding="unicode")
    return Scenario(config, Path(net))


def _figures(spec: RunSpec, summary: dict[str, Any], out: Path) -> dict[str, Any]:
    """The run's row of figures from its files."""
    factors = spec.factors
    share = factors.equipped_share or 0.0  # None in a reference run: no vehicle equipped
    equipped = lambda vehicle_id: share > 0 and is_equipped(vehicle_id, share, spec.seed)  # noqa: E731
    trips = ElementTree.parse(out / TRIPINFO).getroot().findall("tripinfo")
    distance_m = {required_attribute(trip, "id"): float(required_attribute(trip, "routeLength")) for trip in trips}
    time_loss_s = [float(required_attribute(trip, "timeLoss")) for trip in trips]
    with open(out / "cosim" / "entries.csv", newline="", encoding="utf-8") as stream:
        entries = list(csv.DictReader(stream))
    with open(out / "cosim" / "warnings.csv", newline="", encoding="utf-8") as stream:
        onsets = [row for row in csv.DictReader(stream) if int(row["level"]) > int(row["previous_level"])]
    above_vw1 = [row for row in entries if float(row["excess_kmh"]) > 0]
    above_vw2 = [row for row in entries if float(row["speed_kmh"]) > _level2_kmh(row)]
    vehicles = len(distance_m)
    equipped_km = sum(d for vehicle_id, d in distance_m.items() if equipped(vehicle_id)) / 1000.0
    warnings = sum(equipped(row["vehicle_id"]) for row in onsets)
    return {
        "key": spec.key,
        "reference": spec.reference,
        "seed": spec.seed,
        **{name: getattr(factors, name) for name in factors.__dataclass_fields__},
        "status": summary["status"],
        "simulated_until_s": summary["simulated_until_s"],
        "vehicles": vehicles,
        "vehicles_equipped": sum(map(equipped, distance_m)),
        "vehicle_km": sum(distance_m.values()) / 1000.0,
        "vehicle_km_equipped": equipped_km,
        "entries_above_vw1": len(above_vw1),
        "entries_above_vw2": len(above_vw2),
        "share_vehicles_above_vw1": len({row["vehicle_id"] for row in above_vw1}) / vehicles if vehicles else None,
        "share_vehicles_above_vw2": len({row["vehicle_id"] for row in above_vw2}) / vehicles if vehicles else None,
        "warnings": warnings,
        "warnings_per_100_vehicle_km": 100.0 * warnings / equipped_km if equipped_km else None,
        "mean_time_loss_s": sum(time_loss_s) / vehicles if vehicles else None,
        "entry_excess_kmh": [float(row["excess_kmh"]) for row in entries],
    }


def _level2_kmh(entry: dict[str, str]) -> float:
    """The level-2 warning speed V_w2 of an entry's curve part for its category (Table 1), km/h."""
    return warning_speed(float(entry["radius_m"]), entry["category"], Level.LEVEL_2)
