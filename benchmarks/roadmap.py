"""How fast a large curvy network loads and profiles, and how much memory it takes; how
fast the bundled real network loads, fitted afresh and from the profile cache.

The network is generated on the fly: a square grid of junctions whose every link is a
two-way road with a reverse-curve "bump" (straight, left arc, right arc, left arc,
straight) built exactly with :mod:`csws.geometry`, then netconverted. The default grid
of 18 x 18 junctions holds about 1,500 lane-km, the size of a regional network a fleet
service loads at start-up. ``netgenerate`` cannot make curved roads, hence plain XML.

The real network (:func:`real_network_load`) is the bundled Bad Hersfeld import, 508
lane-km: once with every road chain fitted, as at the first load of a network, and once
with the fit read from the profile cache (:mod:`csws.curvature.cache`) in a fresh folder
that the first load filled, as at every later load and after ``csws import-osm``.

Run with ``python -m benchmarks.roadmap``.
"""

from __future__ import annotations

import os
import resource
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from benchmarks.command import arguments
from csws.ahead.lookahead import LookAhead
from csws.curvature import radius_profiles
from csws.geometry import Piece, arc, pose_at, sample_pieces, straight
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap, read_sumo_net
from csws.sumo.netbuild import netconvert, shape_text

REAL_NET = networks_dir() / "badhersfeld.net.xml.gz"
#: How long the real network may take to load, s: fitted before (the profile cache), and afresh.
REAL_LOAD_TARGET_S = 3.0
#: How long the first look-ahead on any lane of a loaded real network may take, ms, and on
#: how many lanes it is timed.
FIRST_LOOKAHEAD_TARGET_MS = 10.0
FIRST_LOOKAHEADS = 300

#: One grid link: a reverse-curve bump whose ends share the same heading and lateral
#: position, so the links close into a square grid. Its arcs are 250 m (inside R_c).
LINK_PIECES: tuple[Piece, ...] = (
    straight(430.0),
    arc(250.0, 20.0, "left"),
    arc(250.0, 40.0, "right"),
    arc(250.0, 20.0, "left"),
    straight(430.0),
)


def _link_chord_m() -> float:
    """Distance between the two ends of a link, m: the grid spacing."""
    total_m = sum(piece.length_m for piece in LINK_PIECES)
    x, y, _ = pose_at(LINK_PIECES, np.array([total_m]))
    return float(np.hypot(x[0], y[0]))


def _grid_links(junctions_per_side: int) -> list[tuple[tuple[int, int], tuple[int, int], float]]:
    """Each link of the grid once: (start junction, end junction, heading in rad)."""
    links = []
    for i in range(junctions_per_side):
        for j in range(junctions_per_side):
            if i + 1 < junctions_per_side:
                links.append(((i, j), (i + 1, j), 0.0))
            if j + 1 < junctions_per_side:
                links.append(((i, j), (i, j + 1), np.pi / 2))
    return links


def _edge_element(from_id: str, to_id: str, xy: np.ndarray) -> str:
    """A one-lane plain XML edge along ``xy``."""
    edge_id = f"{from_id}-{to_id}"
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="22.22" '
        f'name="road {edge_id}" type="rural" shape="{shape_text(xy)}"/>'
    )


def write_curvy_grid(directory: Path, junctions_per_side: int = 18, vertex_spacing_m: float = 5.0) -> Path:
    """Write and netconvert the curvy grid network; return the ``.net.xml`` path.

    Parameters
    ----------
    directory
        Folder for the plain XML and the network.
    junctions_per_side
        The grid has ``junctions_per_side ** 2`` junctions; every link is a two-way road.
    vertex_spacing_m
        Shape vertex spacing along every link, m.
    """
    spacing_m = _link_chord_m()
    nodes = [
        f'<node id="n{i}_{j}" x="{i * spacing_m:.3f}" y="{j * spacing_m:.3f}" type="priority"/>'
        for i in range(junctions_per_side)
        for j in range(junctions_per_side)
    ]
    edges = []
    for (i, j), (k, m), heading_rad in _grid_links(junctions_per_side):
        xy, _ = sample_pieces(LINK_PIECES, vertex_spacing_m, (i * spacing_m, j * spacing_m), heading_rad)
        edges.append(_edge_element(f"n{i}_{j}", f"n{k}_{m}", xy))
        edges.append(_edge_element(f"n{k}_{m}", f"n{i}_{j}", xy[::-1]))
    net_path = netconvert(
        "<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n",
        "<edges>\n" + "\n".join(edges) + "\n</edges>\n",
        directory / "grid.net.xml",
    )
    return net_path


def _fixes_near_lanes(road_map: RoadMap, count: int, seed: int = 1) -> np.ndarray:
    """``count`` positions scattered up to 5 m around random shape vertices, like GNSS fixes, m."""
    rng = np.random.default_rng(seed)
    lane_ids = road_map.lane_ids
    vertex_counts = np.array([len(road_map.lane_shape(lane_id)) for lane_id in lane_ids])
    lanes = rng.choice(len(lane_ids), size=count, p=vertex_counts / vertex_counts.sum())
    shapes = [road_map.lane_shape(lane_ids[i]) for i in lanes]
    vertices = np.array([shape[rng.integers(0, len(shape))] for shape in shapes])
    return vertices + rng.uniform(-5.0, 5.0, vertices.shape)


def run(junctions_per_side: int = 18, fix_count: int = 10_000) -> dict:
    """Generate the grid, load it, profile it and match GNSS-like fixes on it; return the figures.

    Returns
    -------
    dict
        Seconds: ``generate_s`` (plain XML + netconvert), ``parse_s`` (sumolib reads
        the network), ``build_s`` (the road map: arrays, radius profiles and curves of
        every lane), ``profile_s`` (of which the one ``radius_profiles`` call),
        ``index_s`` (spatial index, built on the first look-up) and ``match_s``
        (``fix_count`` fixes matched within 10 m). Sizes: ``lanes``,
        ``internal_lanes``, ``vertices``, ``lane_km``, ``curves``, ``matches``,
        ``stored_mb`` (the road map's arrays) and ``max_rss_mb`` (the process).
    """
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        net_path = write_curvy_grid(Path(folder), junctions_per_side)
        generated = time.perf_counter()
        net = read_sumo_net(net_path)
    parsed = time.perf_counter()
    road_map = RoadMap.from_net(net, cache=False)
    built = time.perf_counter()
    del net
    radius_profiles([road_map.lane_shape(lane_id) for lane_id in road_map.lane_ids])
    profiled = time.perf_counter()
    fixes = _fixes_near_lanes(road_map, fix_count)
    before_index = time.perf_counter()
    first_x, first_y = fixes[0]
    road_map.nearest_lanes(first_x, first_y, radius_m=10.0)
    indexed = time.perf_counter()
    matches = road_map.match_points(fixes, radius_m=10.0)
    matched = time.perf_counter()
    return {
        "generate_s": round(generated - started, 2),
        "parse_s": round(parsed - generated, 2),
        "build_s": round(built - parsed, 2),
        "profile_s": round(profiled - built, 2),
        "index_s": round(indexed - before_index, 3),
        "match_s": round(matched - indexed, 3),
        "lanes": len(road_map.lane_ids),
        "internal_lanes": sum(road_map.lane(lane_id).is_internal for lane_id in road_map.lane_ids),
        "vertices": road_map.vertex_count,
        "lane_km": round(road_map.total_length_m / 1000.0, 1),
        "curves": len(road_map.curves()),
        "fixes": fix_count,
        "matches": len(matches),
        "stored_mb": round(road_map.nbytes / 1e6, 1),
        "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
    }


@contextmanager
def profile_cache_in(cache_dir: str) -> Iterator[None]:
    """Use the profile cache folder ``cache_dir`` (an empty string: no cache) inside the block."""
    previous = os.environ.get("CSWS_CACHE_DIR")
    os.environ["CSWS_CACHE_DIR"] = cache_dir
    try:
        yield
    finally:
        if previous is None:
            del os.environ["CSWS_CACHE_DIR"]
        else:
            os.environ["CSWS_CACHE_DIR"] = previous


def _timed_load(cache_dir: str) -> tuple[float, RoadMap]:
    """Seconds :meth:`RoadMap.load` takes on the real network with the profile cache in
    ``cache_dir`` (see :func:`profile_cache_in`), and the map."""
    with profile_cache_in(cache_dir):
        started = time.perf_counter()
        road_map = RoadMap.load(REAL_NET)
        return time.perf_counter() - started, road_map


def first_lookaheads_ms(road_map: RoadMap, count: int = FIRST_LOOKAHEADS, seed: int = 3) -> np.ndarray:
    """Milliseconds of the first look-ahead on ``count`` lanes of the map drawn at random
    (normal lanes that a truck may use), each from a fresh :class:`csws.ahead.lookahead.LookAhead`,
    so that nothing of an earlier query is reused: an N vehicle at 80 km/h mid-lane."""
    rng = np.random.default_rng(seed)
    lanes = [
        lane_id
        for lane_id in road_map.lane_ids
        if not road_map.lane(lane_id).is_internal and "truck" in road_map.lane(lane_id).allowed_vclasses
    ]
    took_ms = []
    for lane_id in rng.choice(lanes, size=min(count, len(lanes)), replace=False):
        lookahead = LookAhead(road_map)
        started = time.perf_counter()
        lookahead(str(lane_id), road_map.lane(str(lane_id)).length_m / 2.0, 80.0, "N")
        took_ms.append((time.perf_counter() - started) * 1000.0)
    return np.array(took_ms)


def real_network_load() -> dict:
    """Seconds to load the bundled real network (parse, arrays, road chains, profiles and
    curves): ``fit_load_s`` fitting every chain, ``cached_load_s`` reading the fit back;
    and the first look-ahead on fresh lanes of the loaded map, ms (:func:`first_lookaheads_ms`)."""
    fit_s, _ = _timed_load("")
    with tempfile.TemporaryDirectory(prefix="csws-bench-cache-") as folder:
        _timed_load(folder)
        cached_s, road_map = _timed_load(folder)
    first_ms = first_lookaheads_ms(road_map)
    return {
        "network": REAL_NET.name,
        "fit_load_s": round(fit_s, 2),
        "cached_load_s": round(cached_s, 2),
        "lanes": len(road_map.lane_ids),
        "lane_km": round(road_map.total_length_m / 1000.0, 1),
        "curves": len(road_map.curves()),
        "first_lookahead_ms_p50": round(float(np.median(first_ms)), 2),
        "first_lookahead_ms_max": round(float(first_ms.max()), 2),
        "first_lookaheads": len(first_ms),
    }


def main() -> None:
    """Print the figures of :func:`run` and :func:`real_network_load`, one per line."""
    arguments("benchmarks.roadmap", __doc__)
    for name, value in (run() | real_network_load()).items():
        print(f"{name:>16}: {value}")


if __name__ == "__main__":
    main()
