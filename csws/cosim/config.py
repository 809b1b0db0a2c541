"""What a co-simulation runs and how: the SUMO scenario and the run's settings.

The scenario is a SUMO configuration, a network with route files, or the bundled fleet
(optionally with a generated fleet of a given size); :class:`CosimConfig` adds the step
length, the interface to SUMO, who answers (library or service), the driver-response model
and what is recorded.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.etree import ElementTree

from .cli import EVALUATION_MODES, SYSTEMS
from .driver import DriverSettings

__all__ = [
    "TIMESERIES_PERIOD_S",
    "CosimConfig",
    "Scenario",
    "bundled_scenario",
    "default_timeseries_every",
    "ignored_options",
    "scenario_from_args",
]

#: The command's time series (and FCD export) keeps one step per this much simulated time by default, s.
TIMESERIES_PERIOD_S = 1.0


def default_timeseries_every(step_length_s: float) -> int:
    """The command's default ``--timeseries-every``: the steps in :data:`TIMESERIES_PERIOD_S` (at least 1).

    A step the time series keeps reads and evaluates every vehicle, so a full series costs what
    evaluating every vehicle at every step costs; a sampled one, as SUMO's FCD export with a period,
    only at those steps.
    """
    return max(1, round(TIMESERIES_PERIOD_S / step_length_s))


@dataclass(frozen=True)
class Scenario:
    """A SUMO scenario: a configuration, or a network with route files.

    Attributes
    ----------
    config
        A ``.sumocfg``, or None.
    net
        The network (read from the configuration when one is given).
    routes
        Route files beyond the configuration's.
    """

    config: Path | None
    net: Path
    routes: tuple[Path, ...] = ()


@dataclass(frozen=True)
class CosimConfig:
    """How to run a co-simulation.

    Attributes
    ----------
    scenario
        What to simulate.
    out
        Output folder.
    step_length_s
        SUMO's step length, s (also the engine's update period).
    end_s
        Stop at this simulation time, s; None runs until every vehicle has arrived.
    interface
        ``libsumo``, ``traci`` or ``gui``.
    service_url
        Ask this csws service instead of the library.
    service_api_key
        The fleet's API key for that service (sent as ``Authorization: Bearer``), or None.
    driver
        The driver-response model, or None.
    seed
        SUMO's random seed.
    evaluate
        False runs SUMO and reads the fleet without asking for warnings (a baseline).
    progress
        Show how far the run is on stderr (:class:`csws.cli.progress.Progress`).
    timeseries
        How the time series is kept: ``parquet``, ``csv`` or ``none`` (:mod:`csws.cosim.timeseries`).
    timeseries_every
        Keep every this many steps in the time series (the command's default:
        :func:`default_timeseries_every`, one step per simulated second).
    systems
        The warning systems evaluated: ``csws`` (curve speed warning) and ``fcw`` (forward
        collision warning, :mod:`csws.cosim.fcw`), either or both.
    fcd
        Also write the run as SUMO's FCD export with each vehicle's warning to this file
        (:mod:`csws.cosim.fcd`), at the steps the time series keeps; None writes none.
    evaluation
        ``scheduled``: evaluate a vehicle only from where a curve warning can arise
        (:mod:`csws.cosim.schedule`) or an object can come within its FCW's range of concern
        (:mod:`csws.cosim.fcw_schedule`), and every vehicle at the steps the time series or the FCD
        export keeps; ``every-step``: every vehicle at every step. Scheduling applies to runs in
        this process: with a service, every vehicle is evaluated at every step.
    """

    scenario: Scenario
    out: Path
    step_length_s: float = 0.1
    end_s: float | None = None
    interface: str = "libsumo"
    service_url: str | None = None
    service_api_key: str | None = field(default=None, repr=False)
    driver: DriverSettings | None = None
    seed: int = 0
    evaluate: bool = True
    progress: bool = False
    timeseries: str = "parquet"
    timeseries_every: int = 1
    systems: tuple[str, ...] = ("csws",)
    fcd: Path | None = None
    evaluation: str = "scheduled"

    def __post_init__(self) -> None:
        if self.evaluation not in EVALUATION_MODES:
            raise ValueError(f"--evaluate takes one of {', '.join(EVALUATION_MODES)}, got {self.evaluation!r}")
        if not self.systems or not set(self.systems) <= set(SYSTEMS):
            raise ValueError(f"--systems takes one or both of {', '.join(SYSTEMS)}, got {','.join(self.systems)!r}")
        if self.service_api_key is not None and self.service_url is None:
            raise ValueError("an API key is for a service: give --service URL with it")
        if "fcw" in self.systems and self.service_url is not None:
            raise ValueError(
                "the forward collision warning is evaluated in this process only: drop --service, "
                "or run --systems csws with it"
            )

    @property
    def fcw(self) -> bool:
        """Whether the forward collision warning is evaluated."""
        return self.evaluate and "fcw" in self.systems

    @property
    def scheduled(self) -> bool:
        """Whether vehicles are evaluated only where a warning can arise (runs in this process)."""
        return self.evaluation == "scheduled" and self.evaluate and self.service_url is None


def bundled_scenario() -> Scenario:
    """The fleet on the bundled fleet network (``networks/fleet_scenario/fleet.sumocfg``)."""
    from csws.networks.fleet import FLEET_NAME, fleet_dir

    return _config_scenario(fleet_dir() / f"{FLEET_NAME}.sumocfg")


def _config_scenario(config: Path) -> Scenario:
    """A scenario from a ``.sumocfg``: its network is read from it, relative to its folder."""
    if not config.is_file():
        raise ValueError(f"no such SUMO configuration: {config}")
    try:
        root = ElementTree.parse(config).getroot()
    except ElementTree.ParseError as exc:
        raise ValueError(f"{config} is not a SUMO configuration: {exc}") from None
    net = root.find("./input/net-file")
    net_file = None if net is None else net.get("value")
    if not net_file:
        raise ValueError(f"{config} names no net-file")
    return Scenario(config, (config.parent / net_file).resolve())


def ignored_options(args: argparse.Namespace) -> str | None:
    """Why the command line asks for something no run would do (an option another one makes
    pointless), or None: such a command is refused rather than run without it."""
    if args.routes and args.net is None and args.sumocfg is None:
        return "--routes needs --net (or --sumocfg, whose routes it adds to)"
    if args.vehicles is not None and (args.net is not None or args.sumocfg is not None):
        return "--vehicles generates a fleet on the bundled fleet network: drop it, or drop --net/--sumocfg"
    if args.api_key is not None and args.service is None:
        return "--api-key-file is for a service: give --service URL with it"
    if args.timeseries_every is not None and args.timeseries == "none" and args.fcd is None:
        return "--timeseries-every thins the time series and --fcd, and --timeseries none keeps neither"
    return None


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The scenario the command line asks for; the bundled fleet by default.

    Raises
    ------
    ValueError
        When a file is missing, or an option would be ignored (:func:`ignored_options`).
    """
    ignored = ignored_options(args)
    if ignored is not None:
        raise ValueError(ignored)
    routes = tuple(args.routes or ())
    for path in routes:
        if not path.is_file():
            raise ValueError(f"no such route file: {path}")
    if args.sumocfg is not None:
        if args.net is not None:
            raise ValueError("give either --sumocfg or --net, not both")
        return replace(_config_scenario(args.sumocfg), routes=routes)
    if args.net is not None:
        if not args.net.is_file():
            raise ValueError(f"no such network: {args.net}")
        if not routes:
            raise ValueError("--net needs --routes (or use --sumocfg)")
        return Scenario(None, args.net, routes)
    scenario = bundled_scenario()
    if args.vehicles is None:
        return scenario
    from csws.networks.fleet import fleet_routes_xml

    args.out.mkdir(parents=True, exist_ok=True)
    generated = args.out / "fleet.rou.xml"
    generated.write_text(fleet_routes_xml(args.vehicles, period_s=args.vehicles, seed=args.seed), encoding="utf-8")
    return Scenario(None, scenario.net, (generated,))
