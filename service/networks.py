"""The networks a service serves: one road map and one :class:`~csws.engine.Engine` each.

By default the service serves the city bundled with csws (:data:`CITY_NETWORK`, Bad Hersfeld, a
geo-referenced OpenStreetMap network), so it answers real streets right after installation. The
bundled test tracks of T/ITS 0091-2018 (:func:`track_network_paths`) are served only when asked
(``csws serve --test-tracks``): they are laid out at the same coordinates as each other and as the
city, so a fix served with them should name its network. A network that cannot be read stops
start-up with one clear line.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from csws.ahead.lookahead import LookAhead, LookAheadSettings
from csws.engine import Engine, EngineSettings
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap

__all__ = [
    "NET_SUFFIXES",
    "HORIZONS_PER_LANE",
    "ServedNetwork",
    "CITY_NETWORK",
    "city_network_paths",
    "track_network_paths",
    "network_name",
    "load_networks",
]

#: File name endings of SUMO networks.
NET_SUFFIXES = (".net.xml", ".net.xml.gz")
#: Longest electronic horizon the service gives, m.
MAX_HORIZON_M = 3000.0
#: The engine of a served network keeps up to this many horizons (paths ahead) per lane of it: a
#: fleet spread over a regional network drives thousands of lanes at once, and a cache smaller
#: than what one fleet tick uses is swept through every tick (10,000 trucks on Bad Hersfeld need
#: about 4,800 horizons, some 8 KB each; the engine's default keeps 4,096).
HORIZONS_PER_LANE = 2
#: The network served by default: the bundled city (OpenStreetMap, geo-referenced).
CITY_NETWORK = "badhersfeld.net.xml.gz"


def network_name(path: Path) -> str:
    """A network's name: its file name without the ``.net.xml[.gz]`` ending."""
    name = path.name
    for suffix in NET_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def city_network_paths() -> list[Path]:
    """The networks served by default: the bundled city alone (:data:`CITY_NETWORK`)."""
    return [networks_dir() / CITY_NETWORK]


def track_network_paths() -> list[Path]:
    """The bundled test tracks of T/ITS 0091-2018 (Tables 3, 7, 8 and 9), sorted by name.

    They share their coordinates (each starts at the origin), so a fix served with them should name
    its network (``"network"`` in a query) or give its lane.
    """
    folder = networks_dir()
    tracks = (p for p in folder.iterdir() if p.name.endswith(NET_SUFFIXES) and p.name != CITY_NETWORK)
    return sorted(tracks, key=lambda p: p.name)


@dataclass
class ServedNetwork:
    """One served network.

    Attributes
    ----------
    name
        Its name (file name without the ending); unique among the served networks.
    path
        Its file.
    road_map
        The map.
    engine
        The warning system on it; it keeps the status of the vehicles last matched here.
    horizon
        Look-ahead for the electronic horizon: a fixed :data:`MAX_HORIZON_M`.
    edge_ids
        Its edges, to check routes.
    """

    name: str
    path: Path
    road_map: RoadMap
    engine: Engine
    horizon: LookAhead
    edge_ids: frozenset[str] = field(repr=False)


def load_networks(
    paths: Sequence[Path],
    settings: EngineSettings = EngineSettings(),
    progress: Callable[[int, int, Path], None] | None = None,
) -> list[ServedNetwork]:
    """Load every network and build its engine; ``progress(number, count, path)`` before each, if given.

    Raises
    ------
    csws.road.roadmap.NetworkError
        If a file cannot be read as a SUMO network (one line, naming the file).
    ValueError
        If no network is given or two share a name.
    """
    if not paths:
        raise ValueError("no network to serve: give at least one --net FILE")
    names = [network_name(Path(p)) for p in paths]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(f"two networks share the name {duplicates[0]!r}: network file names must differ")
    served = []
    for number, (name, path) in enumerate(zip(names, paths, strict=False), start=1):
        if progress is not None:
            progress(number, len(paths), Path(path))
        road_map = RoadMap.load(path, warning_radius_m=settings.lookahead.warning_radius_m)
        cache_size = max(settings.lookahead.cache_size, HORIZONS_PER_LANE * len(road_map.lane_ids))
        engine_settings = replace(settings, lookahead=replace(settings.lookahead, cache_size=cache_size))
        horizon_settings = LookAheadSettings(
            fixed_distance_m=MAX_HORIZON_M,
            warning_radius_m=settings.lookahead.warning_radius_m,
            cache_size=256,
        )
        served.append(
            ServedNetwork(
                name=name,
                path=Path(path),
                road_map=road_map,
                engine=Engine(road_map, engine_settings),
                horizon=LookAhead(road_map, horizon_settings, settings.warning),
                edge_ids=frozenset(road_map.lane(lane_id).edge_id for lane_id in road_map.lane_ids),
            )
        )
    return served
