"""A junction town for map matching tests: a main road through a junction with side streets, each
side street with a tight curve soon after the junction; and GNSS-like fixes of a vehicle driving
a path of lanes (position noise, heading noise), built with a fixed random generator."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from builders import edge_xml, node_xml

from csws.geometry import arc, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.sumo.netbuild import netconvert

#: The junction J of the main road lies here; the main road runs east from x = 0 to 600 m along y = 0.
JUNCTION_XY = (300.0, 0.0)
#: The south side street runs this far straight from the junction before its curve, m.
SIDE_STRAIGHT_M = 40.0
#: Radius of the side streets' curves, m: a level-2 warning for a vehicle at 50 km/h.
SIDE_RADIUS_M = 20.0


def _side_street(heading_rad: float, turn: str) -> np.ndarray:
    """A side street leaving the junction at ``heading_rad``: straight, a 90 degree curve, straight."""
    pieces = (straight(SIDE_STRAIGHT_M), arc(SIDE_RADIUS_M, 90.0, turn), straight(120.0))
    xy, _ = sample_pieces(pieces, 1.0, JUNCTION_XY, heading_rad)
    return xy


def build_junction_town(folder: Path) -> RoadMap:
    """The road map of :func:`write_junction_town`."""
    return RoadMap.load(write_junction_town(folder))


def write_junction_town(folder: Path) -> Path:
    """Write and netconvert the main road W -> J -> E (priority 3) and two side streets from J (priority 1):
    S south then curving west, N north then curving east."""
    south, north = _side_street(-math.pi / 2, "right"), _side_street(math.pi / 2, "right")
    nodes = [
        node_xml("W", (0.0, 0.0)),
        node_xml("J", JUNCTION_XY),
        node_xml("E", (600.0, 0.0)),
        node_xml("S", south[-1]),
        node_xml("N", north[-1]),
    ]
    edges = [
        edge_xml("WJ", "W", "J", np.array([(0.0, 0.0), JUNCTION_XY]), priority=3),
        edge_xml("JE", "J", "E", np.array([JUNCTION_XY, (600.0, 0.0)]), priority=3),
        edge_xml("JS", "J", "S", south, priority=1),
        edge_xml("JN", "J", "N", north, priority=1),
    ]
    return netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "town.net.xml"
    )


@dataclass(frozen=True)
class Drive:
    """A vehicle's true positions along a path of lanes at 1 Hz and its noisy fixes.

    Attributes
    ----------
    time_s, lane_id, lane_pos_m
        The true lane and lane position at each fix's time.
    xy, heading_deg
        The noisy fixes (position, GNSS heading).
    true_xy
        The true positions.
    """

    time_s: np.ndarray
    lane_id: list[str]
    lane_pos_m: np.ndarray
    xy: np.ndarray
    heading_deg: np.ndarray
    true_xy: np.ndarray


def drive(
    road_map: RoadMap,
    lanes: list[str],
    speed_mps: float,
    seed: int,
    sigma_m: float = 3.0,
    heading_sigma_deg: float = 5.0,
    start_m: float = 150.0,
    length_m: float = 300.0,
) -> Drive:
    """Drive ``lanes`` (internal lanes filled in) at ``speed_mps`` from ``start_m`` plus a random phase of
    one fix interval, a fix every second, ``length_m`` in all."""
    rng = np.random.default_rng(seed)
    path = road_map.expand_path(lanes)
    shapes = [np.asarray(road_map.lane_shape(lane)) for lane in path]
    lengths = [float(np.hypot(*np.diff(shape, axis=0).T).sum()) for shape in shapes]
    offsets = np.concatenate(([0.0], np.cumsum(lengths)))
    s = start_m + rng.uniform(0.0, speed_mps) + speed_mps * np.arange(int(length_m / speed_mps))
    s = s[s < offsets[-1] - 1.0]
    lane_of = np.searchsorted(offsets, s, side="right") - 1
    true_xy, heading_deg, lane_ids, lane_pos = [], [], [], []
    for si, k in zip(s.tolist(), lane_of.tolist(), strict=True):
        shape = shapes[k]
        vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))))
        along = si - offsets[k]
        x, y = np.interp(along, vertex_s, shape[:, 0]), np.interp(along, vertex_s, shape[:, 1])
        segment = min(int(np.searchsorted(vertex_s, along, side="right")) - 1, len(shape) - 2)
        dx, dy = shape[segment + 1] - shape[segment]
        true_xy.append((x, y))
        heading_deg.append((90.0 - math.degrees(math.atan2(dy, dx))) % 360.0)
        lane_ids.append(path[k])
        lane_pos.append(along * road_map.lane(path[k]).position_factor)
    true = np.array(true_xy)
    noisy_heading = (np.array(heading_deg) + rng.normal(0.0, heading_sigma_deg, len(s))) % 360.0
    return Drive(
        np.arange(len(s), dtype=float),
        lane_ids,
        np.array(lane_pos),
        true + rng.normal(0.0, sigma_m, true.shape),
        noisy_heading,
        true,
    )
