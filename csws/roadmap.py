"""The road map: every lane of a SUMO network with its shape, links and curves.

A :class:`RoadMap` is read once from a ``.net.xml`` (or ``.net.xml.gz``) and then
answers the questions the warning needs about the road ahead:

* which lanes a vehicle at (x, y) may be on, where along them and heading which way
  (:meth:`RoadMap.nearest_lanes`, :meth:`RoadMap.match_points` for many fixes at once);
* where the curves are: per lane (:meth:`RoadMap.lane_curves`, :meth:`RoadMap.curves`)
  and along a path of consecutive lanes (:meth:`RoadMap.path_profile`). A path is
  stitched into one polyline before it is profiled, so a curve that crosses an edge
  boundary or a junction is one curve with one start (3.4) and one end (3.5), and the
  look-ahead distance (3.9) to it and to its CPOI (3.11) is measured along the path.

Every lane of the network is kept, internal junction lanes included, because a vehicle
drives through them and they carry the turns: a path runs normal lane -> internal
"via" lane(s) -> next normal lane, exactly as SUMO moves vehicles. Pedestrian crossings
and walking areas are left out.

Junction manoeuvres are not curves of the road. A turn from one road into another (an
internal lane whose connection leaves the road chain, :mod:`csws.roadchain`) or a drive
round a roundabout (the edges of the network's ``<roundabout>`` elements) is taken at
junction speed, not a bend taken at road speed. A curve of the road with a node inside
it (a way split, a side road joining) is a curve whole: the path runs on through the
internal lane that continues the road, taken as one chord across the junction
(:meth:`RoadMap.path_profile`). A path offers the warning only its road curves
(:meth:`PathProfile.road_curves`): a curve that turns mostly near junction-turn lanes
(:data:`JUNCTION_TURN_SHARE`, :data:`JUNCTION_MARGIN_M`) is a junction manoeuvre.

Networks imported from OpenStreetMap are geo-referenced: :meth:`RoadMap.xy_to_lonlat`
and :meth:`RoadMap.lonlat_to_xy` (and their vectorised ``*_many`` variants) convert with
the network's own projection (UTM for an OSM import), and :meth:`RoadMap.curves_geojson`
gives the curve index in WGS84.

Storage is columnar: the vertices of all lanes sit in one ``(n, 2)`` array with an
offset per lane, and all lanes are profiled in one :func:`csws.curvature.radius_profiles`
call, so a regional network of some 1,500 lane-km loads and profiles in seconds.

Lane positions follow SUMO: a lane position runs from 0 to the lane's ``length``
attribute, which may differ from the length of its shape (outer lanes of a curve,
internal lanes, edges with a custom length); SUMO maps between them by the factor
``length / shape length``, and so does this module. Radius profiles and the
:class:`~csws.curvature.Curve` objects they yield are in shape arc length.
"""

from __future__ import annotations

import csv
import json
import math
import xml.sax
import zlib
from dataclasses import dataclass
from functools import cached_property
from itertools import chain, pairwise
from pathlib import Path
from typing import Sequence, TextIO

import numpy as np
import shapely
import sumolib

from .curvature import ConstantRadiusPart, Curve, RadiusProfile, curves_from_profile, radius_profile, radius_profiles
from .roadchain import road_continuations
from .standard import DEFAULT_WARNING_RADIUS_M

__all__ = [
    "CURVE_FIELDS",
    "JOINT_TOLERANCE_M",
    "JUNCTION_MARGIN_M",
    "JUNCTION_TURN_SHARE",
    "Lane",
    "LaneCurve",
    "LaneMatch",
    "LaneMatches",
    "NetworkError",
    "PathProfile",
    "RoadMap",
    "read_sumo_net",
]

#: Two consecutive lanes of a path whose joint points are closer than this are joined
#: at one vertex, m. SUMO writes coordinates to the centimetre and makes the lanes of a
#: connection meet exactly; a few-centimetre segment at the joint would otherwise read
#: as a spurious sharp bend.
JOINT_TOLERANCE_M = 0.1
#: Lane shapes are simplified within this distance for position look-ups, m.
MATCH_TOLERANCE_M = 0.01

#: A curve is a junction manoeuvre, not a curve of the road, when at least this share of
#: its turning angle (3.6) lies on junction lanes: turns into another road and roundabouts.
JUNCTION_TURN_SHARE = 0.5

#: Lane shapes within this distance of a junction-turn lane are netconvert's, not the
#: mapped road's, m: it cuts the lanes back to the junction border and joins them with
#: internal lanes of its own making, which bends the last metres of the lanes too.
JUNCTION_MARGIN_M = 10.0

#: The columns of :meth:`RoadMap.write_curves`, in order.
CURVE_FIELDS = ("lane_id", "start_pos_m", "end_pos_m", "min_radius_m", "angle_deg", "direction")

#: SUMO edge functions kept, and the name each is known by here.
_KEPT_FUNCTIONS = {"": "normal", "internal": "internal"}

#: What sumolib's reader raises on a file that is not a readable network.
_READ_ERRORS = (
    xml.sax.SAXException,
    OSError,
    EOFError,
    zlib.error,
    UnicodeDecodeError,
    KeyError,
    IndexError,
    ValueError,
    TypeError,
    AttributeError,
)


class NetworkError(ValueError):
    """A file that cannot be used as a road map: missing, not a SUMO network, or empty."""


@dataclass(frozen=True, slots=True)
class Lane:
    """The SUMO attributes of one lane.

    Attributes
    ----------
    lane_id, edge_id
        SUMO ids; internal lanes start with ``:``.
    index
        Index of the lane in its edge (0 is the rightmost).
    function
        ``"normal"`` or ``"internal"`` (a lane inside a junction).
    street_name, road_type
        The edge's ``name`` and ``type`` attributes ("" when absent).
    speed_limit_mps
        The lane's speed limit, m/s.
    length_m
        SUMO length: lane positions run from 0 to this, m.
    shape_length_m
        Length of the lane's polyline, m.
    allowed_vclasses
        The vehicle classes allowed on the lane.
    in_roundabout
        Whether the lane belongs to a roundabout: its edge is listed in one of the
        network's ``<roundabout>`` elements, or it is an internal lane of one of its
        junctions.
    continues_road
        For an internal lane, whether its connection continues the road through the
        junction (a way split, a node inside a bend, the straight-ahead or priority
        continuation: :func:`csws.roadchain.road_continuations`) rather than turning
        into another road. Always False for normal lanes.
    """

    lane_id: str
    edge_id: str
    index: int
    function: str
    street_name: str
    road_type: str
    speed_limit_mps: float
    length_m: float
    shape_length_m: float
    allowed_vclasses: frozenset[str]
    in_roundabout: bool = False
    continues_road: bool = False

    @property
    def is_internal(self) -> bool:
        """Whether the lane lies inside a junction."""
        return self.function == "internal"

    @property
    def is_junction(self) -> bool:
        """Whether driving the lane is a junction manoeuvre: a turn from one road into another
        (an internal lane that does not continue the road) or a roundabout."""
        return (self.is_internal and not self.continues_road) or self.in_roundabout

    @property
    def position_factor(self) -> float:
        """Lane position per metre of shape: SUMO's ``length / shape length`` (1 for a point shape)."""
        return self.length_m / self.shape_length_m if self.shape_length_m > 0 else 1.0


@dataclass(frozen=True)
class LaneCurve:
    """A curve (3.4-3.5) found on one lane, with its ends as SUMO lane positions.

    Attributes
    ----------
    lane_id
        The lane the curve lies on.
    start_pos_m, end_pos_m
        Lane positions of the curve start (3.4) and end (3.5), m.
    curve
        The curve itself, in the lane's shape arc length.
    """

    lane_id: str
    start_pos_m: float
    end_pos_m: float
    curve: Curve

    def as_record(self) -> dict[str, str | float]:
        """The :data:`CURVE_FIELDS` of the curve, lengths and angles to the centimetre / hundredth degree."""
        return {
            "lane_id": self.lane_id,
            "start_pos_m": round(self.start_pos_m, 2),
            "end_pos_m": round(self.end_pos_m, 2),
            "min_radius_m": round(self.curve.min_radius_m, 2),
            "angle_deg": round(self.curve.angle_deg, 2),
            "direction": self.curve.direction,
        }


@dataclass(frozen=True)
class LaneMatch:
    """One lane near a position.

    Attributes
    ----------
    lane_id
        The candidate lane.
    distance_m
        Distance from the position to the lane's shape, m.
    lane_pos_m
        Lane position of the position's projection onto the shape, m.
    heading_rad
        Driving direction of the lane there, radians counter-clockwise from +x
        (the convention of :mod:`csws.geometry`).
    """

    lane_id: str
    distance_m: float
    lane_pos_m: float
    heading_rad: float


@dataclass(frozen=True)
class LaneMatches:
    """Lanes near many positions, as parallel arrays (one row per position-lane pair).

    Rows are sorted by ``point_index`` and, for each point, by ``distance_m``; a point
    with no lane within the search radius has no row.

    Attributes
    ----------
    point_index
        Index of the position in the query, ``(k,)`` int.
    lane_id
        Candidate lane ids, ``(k,)`` object array of str.
    distance_m, lane_pos_m, heading_rad
        As in :class:`LaneMatch`, ``(k,)`` float arrays.
    """

    point_index: np.ndarray
    lane_id: np.ndarray
    distance_m: np.ndarray
    lane_pos_m: np.ndarray
    heading_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.point_index)

    def for_point(self, point_index: int) -> list[LaneMatch]:
        """The candidates of one position, nearest first."""
        rows = np.flatnonzero(self.point_index == point_index)
        return [
            LaneMatch(str(self.lane_id[i]), *map(float, (self.distance_m[i], self.lane_pos_m[i], self.heading_rad[i])))
            for i in rows
        ]


@dataclass(frozen=True)
class PathProfile:
    """The radius profile of consecutive lanes stitched into one polyline.

    The path arc length ``s`` starts at 0 at the first vertex of the first lane. The
    look-ahead distance (3.9) to a curve start or to a CPOI (3.11) is a difference of
    two path arc lengths.

    Attributes
    ----------
    lane_ids
        The lanes in driving order, internal via lanes included.
    xy
        The stitched polyline, ``(n, 2)``, m.
    profile
        Its radius profile.
    lane_start_s
        Path arc length at the first shape point of each lane, ``(len(lane_ids),)``, m.
    lane_shape_length_m, lane_position_factor
        Length of each lane's shape on the path and SUMO's position factor for it (see
        :class:`Lane`; an internal lane that continues the road is one chord here).
    lane_is_junction
        Whether each lane is a junction manoeuvre (:attr:`Lane.is_junction`).
    """

    lane_ids: tuple[str, ...]
    xy: np.ndarray
    profile: RadiusProfile
    lane_start_s: np.ndarray
    lane_shape_length_m: np.ndarray
    lane_position_factor: np.ndarray
    lane_is_junction: np.ndarray

    @property
    def length_m(self) -> float:
        """Arc length of the whole path, m."""
        return float(self.profile.s[-1])

    def curves(self, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
        """The curves (radius <= ``warning_radius_m``, 3.2-3.5) along the path, in path arc length."""
        return curves_from_profile(self.profile, warning_radius_m)

    def road_curves(self, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
        """The curves of the road along the path: :meth:`curves` without junction geometry.

        A curve is a junction manoeuvre, and left out, when at least
        :data:`JUNCTION_TURN_SHARE` of its turning angle lies in junction zones (junction
        lanes, widened by :data:`JUNCTION_MARGIN_M`). Of the other curves, the parts lying
        mostly in a junction zone are left out: there the shape is netconvert's
        construction, not the mapped road, and the road's radius is that of the parts
        either side.
        """
        zones = self.junction_zones()
        road_curves = []
        for curve in self.curves(warning_radius_m):
            length_m = np.array([part.end_s - part.start_s for part in curve.parts])
            radius_m = np.array([part.radius_m for part in curve.parts])
            in_zone_m = np.array([_overlap_m(zones, part.start_s, part.end_s) for part in curve.parts])
            if np.sum(in_zone_m / radius_m) >= JUNCTION_TURN_SHARE * np.sum(length_m / radius_m):
                continue
            kept = [part for part, inside, length in zip(curve.parts, in_zone_m, length_m) if inside < 0.5 * length]
            if kept:
                road_curves.append(_curve_of_parts(kept, curve.direction))
        return road_curves

    def junction_zones(self) -> np.ndarray:
        """Path arc-length intervals of the junction lanes widened by :data:`JUNCTION_MARGIN_M`,
        merged where they overlap, ``(k, 2)``, m."""
        junction = np.flatnonzero(self.lane_is_junction)
        starts = self.lane_start_s[junction] - JUNCTION_MARGIN_M
        ends = self.lane_start_s[junction] + self.lane_shape_length_m[junction] + JUNCTION_MARGIN_M
        merged: list[list[float]] = []
        for start, end in zip(starts.tolist(), ends.tolist()):
            if merged and start <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], end)
            else:
                merged.append([start, end])
        return np.array(merged, dtype=float).reshape(-1, 2)

    def lane_positions(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map path arc lengths to lanes: for each ``s``, the index into :attr:`lane_ids` and the lane position.

        An ``s`` on a joint belongs to the lane that starts there; ``s`` outside the
        path is clamped to its ends.
        """
        s = np.asarray(s, dtype=float)
        lane = np.clip(np.searchsorted(self.lane_start_s, s, side="right") - 1, 0, len(self.lane_ids) - 1)
        along_shape_m = np.clip(s - self.lane_start_s[lane], 0.0, self.lane_shape_length_m[lane])
        return lane, along_shape_m * self.lane_position_factor[lane]

    def lane_position(self, s: float) -> tuple[str, float]:
        """The lane id and lane position at path arc length ``s`` (see :meth:`lane_positions`)."""
        lane, pos_m = self.lane_positions(np.array([s]))
        return self.lane_ids[int(lane[0])], float(pos_m[0])

    def path_s(self, lane_id: str, lane_pos_m: float) -> float:
        """Path arc length of a lane position on the first occurrence of ``lane_id`` in the path.

        Raises
        ------
        KeyError
            If the lane is not on the path.
        """
        try:
            lane = self.lane_ids.index(lane_id)
        except ValueError:
            raise KeyError(f"lane {lane_id!r} is not on the path") from None
        along_shape_m = np.clip(lane_pos_m / self.lane_position_factor[lane], 0.0, self.lane_shape_length_m[lane])
        return float(self.lane_start_s[lane] + along_shape_m)


def read_sumo_net(path: str | Path) -> sumolib.net.Net:
    """Read a SUMO network with its internal lanes, turning every failure into :class:`NetworkError`.

    Raises
    ------
    NetworkError
        If the file is missing, is not a SUMO network, or has no edges.
    """
    path = Path(path)
    if not path.is_file():
        raise NetworkError(f"no SUMO network at {path}: the file does not exist")
    try:
        net = sumolib.net.readNet(str(path), withInternal=True)
    except _READ_ERRORS as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise NetworkError(f"{path} is not a readable SUMO network ({reason})") from None
    if net.getVersion() is None:
        raise NetworkError(f"{path} is not a SUMO network: it has no <net> root element")
    if not net.getEdges():
        raise NetworkError(f"{path} is an empty SUMO network: it has no edges")
    return net


def _check_shape(lane: sumolib.net.lane.Lane) -> None:
    """NetworkError naming the lane if its shape is not a polyline of finite coordinates (SUMO refuses it too)."""
    shape = lane.getShape()
    if len(shape) < 2:
        raise NetworkError(f"lane {lane.getID()} has a broken shape of {len(shape)} point(s); a lane needs two or more")
    if not np.isfinite(np.asarray(shape, dtype=float)).all():
        raise NetworkError(f"lane {lane.getID()} has a shape coordinate that is not a finite number")


def _lane_record(lane: sumolib.net.lane.Lane, shape_length_m: float, in_roundabout: bool, continues_road: bool) -> Lane:
    """The :class:`Lane` attributes of a sumolib lane."""
    edge = lane.getEdge()
    return Lane(
        lane_id=lane.getID(),
        edge_id=edge.getID(),
        index=lane.getIndex(),
        function=_KEPT_FUNCTIONS[edge.getFunction()],
        street_name=edge.getName() or "",
        road_type=edge.getType() or "",
        speed_limit_mps=float(lane.getSpeed()),
        length_m=float(lane.getLength()),
        shape_length_m=shape_length_m,
        allowed_vclasses=frozenset(lane.getPermissions()),
        in_roundabout=in_roundabout,
        continues_road=continues_road,
    )


def _internal_edge_junction(edge_id: str) -> str:
    """The junction of an internal edge: SUMO names them ``:JUNCTION_INDEX``."""
    return edge_id[1:].rsplit("_", 1)[0]


def _roundabout_edge_ids(net: sumolib.net.Net) -> frozenset[str]:
    """Ids of the edges in a roundabout: those of the ``<roundabout>`` elements and the
    internal edges of their junctions."""
    roundabouts = net.getRoundabouts()
    edge_ids = {edge_id for roundabout in roundabouts for edge_id in roundabout.getEdges()}
    junction_ids = {node_id for roundabout in roundabouts for node_id in roundabout.getNodes()}
    internal_ids = {
        edge.getID()
        for edge in net.getEdges()
        if edge.getFunction() == "internal" and _internal_edge_junction(edge.getID()) in junction_ids
    }
    return frozenset(edge_ids | internal_ids)


def _successor_ids(lane: sumolib.net.lane.Lane, index: dict[str, int]) -> list[int]:
    """Indices of the lanes reached from the end of a sumolib lane: a connection's via lane, else its target."""
    reached = []
    for connection in lane.getOutgoing():
        target = connection.getViaLaneID() or connection.getToLane().getID()
        if target in index and index[target] not in reached:
            reached.append(index[target])
    return reached


def _continuing_internal_lanes(sumo_lanes: Sequence[sumolib.net.lane.Lane], continuations: frozenset[tuple[str, str]]) -> set[str]:
    """Ids of the internal lanes of the connections that continue a road (edge pairs in ``continuations``)."""
    by_id = {lane.getID(): lane for lane in sumo_lanes}
    continuing: set[str] = set()
    for lane in sumo_lanes:
        for connection in lane.getOutgoing():
            if (lane.getEdge().getID(), connection.getTo().getID()) not in continuations:
                continue
            via = connection.getViaLaneID()
            # An internal lane leads on through further internal lanes (a left turn's wait
            # position) to the connection's target.
            while via in by_id and via not in continuing and by_id[via].getEdge().getFunction() == "internal":
                continuing.add(via)
                following = by_id[via].getOutgoing()
                via = (following[0].getViaLaneID() or following[0].getToLane().getID()) if following else ""
    return continuing


def _geo_reference(net: sumolib.net.Net) -> sumolib.net.Net:
    """A bare sumolib net carrying only the location of ``net``.

    sumolib keeps the ``<location>`` element in the net's ``_location`` mapping and has
    no public getter for all of it; copying it keeps ``convertXY2LonLat`` /
    ``convertLonLat2XY`` available without holding every lane's Python objects.
    """
    location = getattr(net, "_location", {})
    geo = sumolib.net.Net()
    geo.setLocation(
        location.get("netOffset", "0.00,0.00"),
        location.get("convBoundary", "0.00,0.00,0.00,0.00"),
        location.get("origBoundary", "0.00,0.00,0.00,0.00"),
        location.get("projParameter", "!"),
    )
    return geo

def _vertex_arc_length(xy: np.ndarray, vertex_start: np.ndarray) -> np.ndarray:
    """Arc length of every vertex along its own lane, for lanes stored back to back in ``xy``."""
    step_m = np.concatenate(([0.0], np.hypot(*np.diff(xy, axis=0).T)))
    step_m[vertex_start[:-1]] = 0.0
    cumulative_m = np.cumsum(step_m)
    lane_of_vertex = np.repeat(np.arange(len(vertex_start) - 1), np.diff(vertex_start))
    return cumulative_m - cumulative_m[vertex_start[:-1]][lane_of_vertex]


def _compressed_rows(rows: Sequence[Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Ragged integer rows as (row start offsets, concatenated values)."""
    start = np.concatenate(([0], np.cumsum([len(row) for row in rows]))).astype(np.int64)
    return start, np.fromiter(chain.from_iterable(rows), dtype=np.int64, count=int(start[-1]))


def _stitch(shapes: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Join lane shapes in driving order into one polyline.

    A lane's first point is dropped when it repeats the previous lane's last point
    (within :data:`JOINT_TOLERANCE_M`), so the joint is one vertex and no zero-length
    segment is left to disturb the curvature.

    Returns
    -------
    xy
        The polyline, ``(n, 2)``.
    lane_start_s
        Arc length along it at each lane's first point, ``(len(shapes),)``.
    """
    pieces = [shapes[0]]
    first_vertex = [0]
    vertex_count = len(shapes[0])
    for previous, shape in pairwise(shapes):
        joined = bool(np.hypot(*(shape[0] - previous[-1])) <= JOINT_TOLERANCE_M)
        pieces.append(shape[1:] if joined else shape)
        first_vertex.append(vertex_count - 1 if joined else vertex_count)
        vertex_count += len(pieces[-1])
    xy = np.concatenate(pieces)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    return xy, s[first_vertex]


def _overlap_m(intervals: np.ndarray, start_s: float, end_s: float) -> float:
    """Length of ``[start_s, end_s]`` covered by disjoint ``intervals`` ``(k, 2)``, m."""
    return float(np.clip(np.minimum(intervals[:, 1], end_s) - np.maximum(intervals[:, 0], start_s), 0.0, None).sum())


def _curve_of_parts(parts: Sequence[ConstantRadiusPart], direction: str) -> Curve:
    """A curve (3.4-3.8) made of some constant-radius parts of another, in order."""
    return Curve(
        start_s=parts[0].start_s,
        end_s=parts[-1].end_s,
        angle_deg=math.degrees(sum((part.end_s - part.start_s) / part.radius_m for part in parts)),
        direction=direction,
        min_radius_m=min(part.radius_m for part in parts),
        parts=tuple(parts),
    )


def _finite_pairs(values: np.ndarray, what: str) -> np.ndarray:
    """``values`` as a float ``(k, 2)`` array; ValueError when not finite pairs."""
    pairs = np.asarray(values, dtype=float)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"{what} must be pairs, got an array of shape {np.shape(values)}")
    if not np.isfinite(pairs).all():
        raise ValueError(f"{what} must be finite numbers")
    return pairs


def _shape_between(shape: np.ndarray, start_s: float, end_s: float) -> np.ndarray:
    """The part of a polyline between two arc lengths, its ends interpolated, ``(m, 2)``."""
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))))
    inside = (s > start_s) & (s < end_s)
    cut_s = np.concatenate(([start_s], s[inside], [end_s]))
    return np.column_stack((np.interp(cut_s, s, shape[:, 0]), np.interp(cut_s, s, shape[:, 1])))


def _write_table(records: list[dict[str, str | float]], stream: TextIO) -> None:
    """Write records as an aligned text table: ids left-aligned, numbers right-aligned."""
    cells = [list(CURVE_FIELDS)] + [[f"{record[name]}" for name in CURVE_FIELDS] for record in records]
    widths = [max(len(row[column]) for row in cells) for column in range(len(CURVE_FIELDS))]
    for row in cells:
        padded = [
            cell.ljust(width) if name in ("lane_id", "direction") else cell.rjust(width)
            for cell, width, name in zip(row, widths, CURVE_FIELDS)
        ]
        stream.write("  ".join(padded).rstrip() + "\n")


class RoadMap:
    """Every lane of a SUMO network: attributes, shape, successors, radius profile and curves.

    Build one with :meth:`load` (from a file) or :meth:`from_net` (from a sumolib net).
    Lanes are addressed by their SUMO id.

    Attributes
    ----------
    warning_radius_m
        Warning curvature radius R_c (3.2) the per-lane curves were found with, m.
    has_projection
        Whether the network is geo-referenced (see :meth:`xy_to_lonlat`).
    geo
        A sumolib net holding only the network's location, whose
        ``convertXY2LonLat`` / ``convertLonLat2XY`` do the geo-conversions.
    """

    def __init__(
        self,
        lanes: Sequence[Lane],
        xy: np.ndarray,
        vertex_start: np.ndarray,
        successors: Sequence[Sequence[int]],
        geo: sumolib.net.Net,
        warning_radius_m: float = DEFAULT_WARNING_RADIUS_M,
    ) -> None:
        """Profile the lanes and find their curves.

        Parameters
        ----------
        lanes
            The lanes' attributes.
        xy
            Vertices of all lanes back to back, ``(n, 2)``, m.
        vertex_start
            Offset of each lane's first vertex in ``xy`` and ``n`` at the end, ``(len(lanes) + 1,)``.
        successors
            For each lane, the indices of the lanes a vehicle can drive onto from its end.
        geo
            A sumolib net carrying the network's location.
        warning_radius_m
            Warning curvature radius R_c (3.2), m.
        """
        if not (math.isfinite(warning_radius_m) and warning_radius_m > 0):
            raise ValueError(f"warning radius must be a positive number of metres, got {warning_radius_m!r}")
        self.warning_radius_m = float(warning_radius_m)
        self.geo = geo
        self.has_projection = bool(geo.hasGeoProj())
        self._lanes = tuple(lanes)
        self._index = {lane.lane_id: i for i, lane in enumerate(self._lanes)}
        self._xy = np.ascontiguousarray(xy, dtype=float)
        self._vertex_start = np.asarray(vertex_start, dtype=np.int64)
        self._vertex_s = _vertex_arc_length(self._xy, self._vertex_start)
        self._successor_start, self._successor_index = _compressed_rows(successors)
        self._profiles = radius_profiles([self._shape(i) for i in range(len(self._lanes))])
        self._lane_curves = tuple(self._curves_of(i) for i in range(len(self._lanes)))

    # ----------------------------------------------------------------- construction
    @classmethod
    def load(cls, net_path: str | Path, warning_radius_m: float | None = None) -> "RoadMap":
        """Read a ``.net.xml`` / ``.net.xml.gz`` and build its road map.

        Parameters
        ----------
        net_path
            The SUMO network.
        warning_radius_m
            Warning curvature radius R_c (3.2), m; ``None`` for the default
            :data:`csws.standard.DEFAULT_WARNING_RADIUS_M`.

        Raises
        ------
        NetworkError
            If the file is missing, not a SUMO network, or has no lanes.
        """
        net = read_sumo_net(net_path)
        try:
            return cls.from_net(net, warning_radius_m)
        except NetworkError as error:
            raise NetworkError(f"{Path(net_path).name}: {error}") from None

    @classmethod
    def from_net(cls, net: sumolib.net.Net, warning_radius_m: float | None = None) -> "RoadMap":
        """Build the road map of a sumolib net read with ``withInternal=True``.

        Only the location of ``net`` is kept: lanes are copied into arrays so the
        sumolib objects can be freed.
        """
        sumo_lanes = [
            lane for edge in net.getEdges() if edge.getFunction() in _KEPT_FUNCTIONS for lane in edge.getLanes()
        ]
        if not sumo_lanes:
            raise NetworkError("the network has no lanes with a shape")
        for lane in sumo_lanes:
            _check_shape(lane)
        vertex_start = np.concatenate(([0], np.cumsum([len(lane.getShape()) for lane in sumo_lanes]))).astype(np.int64)
        xy = np.array(list(chain.from_iterable(lane.getShape() for lane in sumo_lanes)), dtype=float).reshape(-1, 2)
        shape_length_m = _vertex_arc_length(xy, vertex_start)[vertex_start[1:] - 1]
        index = {lane.getID(): i for i, lane in enumerate(sumo_lanes)}
        successors = [_successor_ids(lane, index) for lane in sumo_lanes]
        roundabout_edges = _roundabout_edge_ids(net)
        continuing = _continuing_internal_lanes(sumo_lanes, road_continuations(net))
        lanes = [
            _lane_record(lane, float(length), lane.getEdge().getID() in roundabout_edges, lane.getID() in continuing)
            for lane, length in zip(sumo_lanes, shape_length_m)
        ]
        radius = DEFAULT_WARNING_RADIUS_M if warning_radius_m is None else warning_radius_m
        return cls(lanes, xy, vertex_start, successors, _geo_reference(net), radius)

    # ----------------------------------------------------------------- lanes
    @cached_property
    def lane_ids(self) -> tuple[str, ...]:
        """Ids of all lanes, internal lanes included, in network order."""
        return tuple(lane.lane_id for lane in self._lanes)

    @property
    def vertex_count(self) -> int:
        """Number of shape vertices over all lanes."""
        return len(self._xy)

    @property
    def total_length_m(self) -> float:
        """Sum of the SUMO lengths of all lanes, m (lane-km x 1000)."""
        return float(sum(lane.length_m for lane in self._lanes))

    @property
    def nbytes(self) -> int:
        """Bytes held by the map's arrays: vertices, arc lengths, links and radius profiles."""
        arrays = [self._xy, self._vertex_s, self._vertex_start, self._successor_start, self._successor_index]
        arrays += [array for p in self._profiles for array in (p.s, p.curvature, p.radius)]
        return int(sum(array.nbytes for array in arrays))

    def has_lane(self, lane_id: str) -> bool:
        """Whether ``lane_id`` is a lane of the map."""
        return lane_id in self._index

    def lane(self, lane_id: str) -> Lane:
        """The SUMO attributes of a lane (:class:`Lane`)."""
        return self._lanes[self._lane_index(lane_id)]

    def lane_shape(self, lane_id: str) -> np.ndarray:
        """The lane's polyline in driving direction, ``(n, 2)``, m (a read-only view)."""
        return self._shape(self._lane_index(lane_id))

    def successors(self, lane_id: str) -> tuple[str, ...]:
        """Lanes a vehicle can drive onto from the end of ``lane_id``.

        From a normal lane these are the internal via lanes of its connections (or the
        next normal lanes where a connection has no via lane); from an internal lane,
        the next internal lane or the normal lane it leads to.
        """
        return tuple(self._lanes[i].lane_id for i in self._successor_indices(self._lane_index(lane_id)))

    def lane_profile(self, lane_id: str) -> RadiusProfile:
        """The radius profile of one lane, in its shape arc length."""
        return self._profiles[self._lane_index(lane_id)]

    def lane_curves(self, lane_id: str) -> tuple[LaneCurve, ...]:
        """The curves (radius <= :attr:`warning_radius_m`) on one lane, in driving order."""
        return self._lane_curves[self._lane_index(lane_id)]

    def curves(self, include_junctions: bool = False) -> list[LaneCurve]:
        """The curves of every lane, lane by lane in network order: the curve index.

        A curve that continues across a junction appears once per lane it touches;
        :meth:`path_profile` joins such pieces into one curve.

        Parameters
        ----------
        include_junctions
            Also list the curves of internal lanes and roundabouts, left out by default:
            a turn into another road or round a roundabout is a junction manoeuvre, and
            an internal lane that continues the road has a shape of netconvert's making
            (the road's curve there is on the normal lanes either side).
        """
        return list(
            chain.from_iterable(
                curves
                for lane, curves in zip(self._lanes, self._lane_curves)
                if include_junctions or not (lane.is_internal or lane.in_roundabout)
            )
        )

    def curves_geojson(self) -> dict:
        """The curve index (:meth:`curves`) as a GeoJSON FeatureCollection in WGS84 (RFC 7946).

        Each curve is a LineString of the lane shape between its start (3.4) and end (3.5)
        in lon/lat degrees, with the :data:`CURVE_FIELDS` and the lane's street name and
        road type as properties.

        Raises
        ------
        ValueError
            If the network has no geo-projection.
        """
        self._require_projection()
        features = []
        for lane_curve in self.curves():
            lane = self.lane(lane_curve.lane_id)
            xy = _shape_between(self.lane_shape(lane.lane_id), lane_curve.curve.start_s, lane_curve.curve.end_s)
            lonlat = np.round(self.xy_to_lonlat_many(xy), 6)
            properties = {**lane_curve.as_record(), "street_name": lane.street_name, "road_type": lane.road_type}
            features.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "LineString", "coordinates": lonlat.tolist()},
                    "properties": properties,
                }
            )
        return {"type": "FeatureCollection", "features": features}

    def write_curves(self, stream: TextIO, fmt: str = "table") -> None:
        """Write :meth:`curves` as ``"table"`` (aligned text), ``"json"`` or ``"csv"`` with :data:`CURVE_FIELDS`."""
        records = [curve.as_record() for curve in self.curves()]
        if fmt == "json":
            json.dump(records, stream, indent=2)
            stream.write("\n")
        elif fmt == "csv":
            writer = csv.DictWriter(stream, fieldnames=CURVE_FIELDS, lineterminator="\n")
            writer.writeheader()
            writer.writerows(records)
        elif fmt == "table":
            _write_table(records, stream)
        else:
            raise ValueError(f"unknown curve format {fmt!r}: use 'table', 'json' or 'csv'")

    # ----------------------------------------------------------------- paths
    def expand_path(self, lane_ids: Sequence[str]) -> tuple[str, ...]:
        """The lanes of a path with the internal via lanes between consecutive lanes filled in.

        ``lane_ids`` may list only normal lanes (as a route does); where a lane does not
        lead directly to the next one, the chain of internal lanes of the connection
        between them is inserted.

        Raises
        ------
        ValueError
            If the path is empty or two consecutive lanes are not connected.
        """
        if not lane_ids:
            raise ValueError("a path needs at least one lane")
        indices = [self._lane_index(lane_ids[0])]
        for following_id in lane_ids[1:]:
            following = self._lane_index(following_id)
            via = self._via_chain(indices[-1], following)
            if via is None:
                raise ValueError(f"lane {following_id!r} does not follow lane {self._lanes[indices[-1]].lane_id!r}")
            indices += via + [following]
        return tuple(self._lanes[i].lane_id for i in indices)

    def path_profile(self, lane_ids: Sequence[str]) -> PathProfile:
        """Stitch consecutive lanes into one polyline and profile it as a whole.

        Because the profile is computed over the joined shape, a curve that crosses an
        edge boundary or a junction is found as one curve (3.4-3.5) and not as pieces
        cut at the lane ends. Internal via lanes missing from ``lane_ids`` are filled in
        (:meth:`expand_path`).
        """
        path = self.expand_path(lane_ids)
        indices = [self._index[lane_id] for lane_id in path]
        shapes = [self._road_shape(i) for i in indices]
        xy, lane_start_s = _stitch(shapes)
        shape_length_m = np.array([np.hypot(*np.diff(shape, axis=0).T).sum() for shape in shapes])
        length_m = np.array([self._lanes[i].length_m for i in indices])
        return PathProfile(
            lane_ids=path,
            xy=xy,
            profile=radius_profile(xy),
            lane_start_s=lane_start_s,
            lane_shape_length_m=shape_length_m,
            lane_position_factor=np.divide(length_m, shape_length_m, out=np.ones(len(indices)), where=shape_length_m > 0),
            lane_is_junction=np.array([self._lanes[i].is_junction for i in indices], dtype=bool),
        )

    # ----------------------------------------------------------------- positions
    def match_points(self, xy: np.ndarray, radius_m: float) -> LaneMatches:
        """All lanes within ``radius_m`` of each of many positions, projected onto each lane.

        Parameters
        ----------
        xy
            Positions in network coordinates, ``(k, 2)``, m.
        radius_m
            Search radius, m (> 0).
        """
        if not (math.isfinite(radius_m) and radius_m > 0):
            raise ValueError(f"search radius must be a positive number of metres, got {radius_m!r}")
        xy = _finite_pairs(xy, "positions")
        point_index, segment_index = self._segment_tree.query(shapely.points(xy), predicate="dwithin",
                                                              distance=radius_m)
        start, end = self._segments[0][segment_index], self._segments[1][segment_index]
        a, b, p = self._xy[start], self._xy[end], xy[point_index]
        direction = b - a
        length_sq = np.einsum("ij,ij->i", direction, direction)
        fraction = np.clip(np.einsum("ij,ij->i", p - a, direction) / np.where(length_sq > 0, length_sq, 1.0), 0, 1)
        nearest = a + fraction[:, None] * direction
        distance_m = np.hypot(*(p - nearest).T)
        lane_index = self._segment_lane[segment_index]
        # The nearest segment of each lane for each point: sort by point, lane, distance; keep the first.
        order = np.lexsort((distance_m, lane_index, point_index))
        first = np.ones(order.size, dtype=bool)
        first[1:] = (np.diff(point_index[order]) != 0) | (np.diff(lane_index[order]) != 0)
        keep = order[first]
        keep = keep[np.lexsort((distance_m[keep], point_index[keep]))]
        start, end = start[keep], end[keep]
        along_shape_m = self._vertex_s[start] + fraction[keep] * (self._vertex_s[end] - self._vertex_s[start])
        lane_index = lane_index[keep]
        return LaneMatches(
            point_index=point_index[keep],
            lane_id=self._lane_id_array[lane_index],
            distance_m=distance_m[keep],
            lane_pos_m=along_shape_m * self._position_factor[lane_index],
            heading_rad=np.arctan2(direction[keep, 1], direction[keep, 0]),
        )

    def nearest_lanes(self, x: float, y: float, radius_m: float) -> list[LaneMatch]:
        """The lanes within ``radius_m`` of (x, y), nearest first (see :meth:`match_points`)."""
        return self.match_points(np.array([[x, y]]), radius_m).for_point(0)

    # ----------------------------------------------------------------- geo-reference
    def xy_to_lonlat(self, x: float, y: float) -> tuple[float, float]:
        """Longitude and latitude (degrees, WGS84) of network coordinates (see :meth:`xy_to_lonlat_many`)."""
        lon, lat = self.xy_to_lonlat_many(np.array([[x, y]], dtype=float))[0]
        return float(lon), float(lat)

    def lonlat_to_xy(self, lon: float, lat: float) -> tuple[float, float]:
        """Network coordinates (m) of a longitude and latitude in degrees (see :meth:`lonlat_to_xy_many`)."""
        x, y = self.lonlat_to_xy_many(np.array([[lon, lat]], dtype=float))[0]
        return float(x), float(y)

    def xy_to_lonlat_many(self, xy: np.ndarray) -> np.ndarray:
        """Longitudes and latitudes (degrees, WGS84) of many network positions, ``(k, 2)`` -> ``(k, 2)``.

        As SUMO and sumolib's ``convertXY2LonLat`` do: the network offset is taken off
        and the network's projection (``projParameter``, UTM for an OSM import) inverted.

        Raises
        ------
        ValueError
            If the network has no geo-projection, or a coordinate is not finite.
        """
        self._require_projection()
        xy = _finite_pairs(xy, "network coordinates")
        offset_x, offset_y = self.geo.getLocationOffset()
        lon, lat = self.geo.getGeoProj()(xy[:, 0] - offset_x, xy[:, 1] - offset_y, inverse=True)
        return np.column_stack((lon, lat))

    def lonlat_to_xy_many(self, lonlat: np.ndarray) -> np.ndarray:
        """Network coordinates (m) of many longitude/latitude pairs in degrees, ``(k, 2)`` -> ``(k, 2)``.

        Raises
        ------
        ValueError
            If the network has no geo-projection, or a longitude is outside [-180, 180]
            or a latitude outside [-90, 90] degrees.
        """
        self._require_projection()
        lonlat = _finite_pairs(lonlat, "lon/lat")
        bad = (np.abs(lonlat[:, 0]) > 180.0) | (np.abs(lonlat[:, 1]) > 90.0)
        if bad.any():
            lon, lat = lonlat[np.flatnonzero(bad)[0]]
            raise ValueError(f"lon/lat out of range: ({lon}, {lat}); longitude is -180..180, latitude -90..90 degrees")
        offset_x, offset_y = self.geo.getLocationOffset()
        x, y = self.geo.getGeoProj()(lonlat[:, 0], lonlat[:, 1])
        return np.column_stack((np.asarray(x) + offset_x, np.asarray(y) + offset_y))

    # ----------------------------------------------------------------- internals
    def _lane_index(self, lane_id: str) -> int:
        try:
            return self._index[lane_id]
        except KeyError:
            raise KeyError(f"no lane {lane_id!r} in the network") from None

    def _shape(self, lane: int) -> np.ndarray:
        view = self._xy[self._vertex_start[lane] : self._vertex_start[lane + 1]]
        view.flags.writeable = False
        return view

    def _road_shape(self, lane: int) -> np.ndarray:
        """The shape a path takes along a lane: the lane's own, but only the two ends of an
        internal lane that continues the road (:attr:`Lane.continues_road`).

        netconvert trims the edges back to the junction border and joins them with a shape
        of its own making, which bends sharply where a side road widens the junction; the
        mapped road is the edges either side. One chord across the junction keeps its
        heading (on a circle a chord is parallel to the tangent at its middle) without the
        made-up bends, so a curve through the junction is fitted from the road's own shape.
        """
        shape = self._shape(lane)
        return shape[[0, -1]] if self._lanes[lane].continues_road and len(shape) > 2 else shape

    def _successor_indices(self, lane: int) -> np.ndarray:
        return self._successor_index[self._successor_start[lane] : self._successor_start[lane + 1]]

    def _curves_of(self, lane: int) -> tuple[LaneCurve, ...]:
        """The curves of one lane with their ends as lane positions."""
        factor = self._lanes[lane].position_factor
        return tuple(
            LaneCurve(self._lanes[lane].lane_id, curve.start_s * factor, curve.end_s * factor, curve)
            for curve in curves_from_profile(self._profiles[lane], self.warning_radius_m)
        )

    def _via_chain(self, lane: int, following: int) -> list[int] | None:
        """Internal lanes leading from the end of ``lane`` to ``following`` ([] if adjacent, None if unreachable)."""
        frontier: list[tuple[int, list[int]]] = [(lane, [])]
        seen = {lane}
        while frontier:
            current, chain_so_far = frontier.pop()
            successors = self._successor_indices(current)
            if following in successors:
                return chain_so_far
            for nxt in successors.tolist():
                if self._lanes[nxt].is_internal and nxt not in seen:
                    seen.add(nxt)
                    frontier.append((nxt, chain_so_far + [nxt]))
        return None

    def _require_projection(self) -> None:
        if not self.has_projection:
            raise ValueError(
                "the network has no geo-projection: it takes network x/y in metres, not lon/lat"
            )

    @cached_property
    def _lane_id_array(self) -> np.ndarray:
        return np.array(self.lane_ids, dtype=object)

    @cached_property
    def _position_factor(self) -> np.ndarray:
        return np.array([lane.position_factor for lane in self._lanes])

    @cached_property
    def _segments(self) -> tuple[np.ndarray, np.ndarray]:
        """First and last vertex of every indexed segment: the lane shapes simplified within
        :data:`MATCH_TOLERANCE_M`, as indices into the shape vertices.

        A dense SUMO shape (a vertex every 0.5 m) becomes one segment per straight and a
        few per curve, so a fix meets a handful of candidates instead of dozens. The kept
        vertices are original ones, so lane positions stay exact there and are
        interpolated in arc length between them.
        """
        lane_of_vertex = np.repeat(np.arange(len(self._lanes)), np.diff(self._vertex_start))
        lines = shapely.linestrings(self._xy, indices=lane_of_vertex)
        simplified = shapely.simplify(lines, MATCH_TOLERANCE_M, preserve_topology=False)
        kept_xy, kept_lane = shapely.get_coordinates(simplified, return_index=True)
        position = {(lane, x, y): i for i, (lane, (x, y)) in enumerate(zip(lane_of_vertex.tolist(), self._xy.tolist()))}
        kept = np.array([position[(lane, x, y)] for lane, (x, y) in zip(kept_lane.tolist(), kept_xy.tolist())])
        # A lane whose kept vertices are not in order (a loop through one point) keeps every vertex.
        disordered = np.unique(kept_lane[1:][(np.diff(kept) <= 0) & (kept_lane[1:] == kept_lane[:-1])])
        if disordered.size:
            keep = ~np.isin(kept_lane, disordered)
            every = np.flatnonzero(np.isin(lane_of_vertex, disordered))
            kept = np.sort(np.concatenate((kept[keep], every)))
        lane = lane_of_vertex[kept]
        segment = (lane[1:] == lane[:-1]) & np.any(self._xy[kept[1:]] != self._xy[kept[:-1]], axis=1)
        return kept[:-1][segment], kept[1:][segment]

    @cached_property
    def _segment_lane(self) -> np.ndarray:
        """The lane of every indexed segment."""
        return np.searchsorted(self._vertex_start, self._segments[0], side="right") - 1

    @cached_property
    def _segment_tree(self) -> shapely.STRtree:
        """Spatial index over the simplified shape segments, built on the first position look-up.

        Segments rather than whole lanes: a projection onto two points is a few numpy
        operations, onto a lane of thousands of vertices a search along all of them.
        """
        start, end = self._segments
        return shapely.STRtree(shapely.linestrings(np.stack((self._xy[start], self._xy[end]), axis=1)))


