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
it (a way split, a side road joining) is a curve whole: each road chain (the lanes a
road continues on, through the internal lanes that continue it, taken as one chord
across the junction) is fitted once, and the curve index and every path read that fit
(:mod:`csws.roadprofile`).

Networks imported from OpenStreetMap are geo-referenced: :meth:`RoadMap.xy_to_lonlat`
and :meth:`RoadMap.lonlat_to_xy` (and their vectorised ``*_many`` variants) convert with
the network's own projection (UTM for an OSM import), and :meth:`RoadMap.curves_geojson`
gives the curve index in WGS84.

Storage is columnar: the vertices of all lanes sit in one ``(n, 2)`` array with an
offset per lane, and all road chains are profiled in one :func:`csws.curvature.radius_profiles`
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
from itertools import chain
from pathlib import Path
from typing import Sequence, TextIO

import numpy as np
import shapely
import sumolib

from .curvature import profile_cache_dir
from .roadchain import road_continuations
from .roadprofile import (
    CURVE_FIELDS,
    LaneCurve,
    PathProfile,
    fit_road_chains,
    index_curves,
    path_profile,
    write_curve_table,
)
from .standard import DEFAULT_WARNING_RADIUS_M

__all__ = [
    "CURVE_FIELDS",
    "Lane",
    "LaneCurve",
    "LaneMatch",
    "LaneMatches",
    "NetworkError",
    "PathProfile",
    "RoadMap",
    "read_sumo_net",
]

#: Lane shapes are simplified within this distance for position look-ups, m.
MATCH_TOLERANCE_M = 0.01

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
    continues_into
        The lane this lane's road continues on ("" where the road ends or turns, on a
        junction turn and on a roundabout): the next lane of its road chain
        (:mod:`csws.roadprofile`).
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
    continues_into: str = ""

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


def _lane_record(
    lane: sumolib.net.lane.Lane, shape_length_m: float, in_roundabout: bool, continues_road: bool, continues_into: str
) -> Lane:
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
        continues_into=continues_into,
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


def _continues_into(
    lane: sumolib.net.lane.Lane, continuations: frozenset[tuple[str, str]], continuing: set[str], roundabout: frozenset[str]
) -> str:
    """The lane a sumolib lane's road continues on, "" where it ends or turns (:attr:`Lane.continues_into`).

    From a normal lane: the lane reached by its connection into the edge that continues
    the road (:func:`csws.roadchain.road_continuations`), the connection's internal lane
    if it has one; of several, the one into the lane of the nearest index. From an
    internal lane that continues the road: the lane it leads on to. A road does not
    continue into, out of or round a roundabout: that is a junction manoeuvre.
    """
    edge_id = lane.getEdge().getID()
    if edge_id in roundabout:
        return ""
    if lane.getEdge().getFunction() == "internal":
        if lane.getID() not in continuing or not lane.getOutgoing():
            return ""
        connection = lane.getOutgoing()[0]
    else:
        candidates = [
            connection
            for connection in lane.getOutgoing()
            if (edge_id, connection.getTo().getID()) in continuations and connection.getTo().getID() not in roundabout
        ]
        if not candidates:
            return ""
        connection = min(candidates, key=lambda c: abs(c.getToLane().getIndex() - lane.getIndex()))
    return connection.getViaLaneID() or connection.getToLane().getID()


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
        *,
        cache: bool = True,
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
        cache
            Whether to read the road chains' fit from the profile cache, and write it there
            when it is not yet (:func:`csws.curvature.profile_cache_dir`).
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
        road_shapes = [self._road_shape(i) for i in range(len(self._lanes))]
        self._chains = fit_road_chains(
            np.array([self._index.get(lane.continues_into, -1) for lane in self._lanes], dtype=np.int64),
            road_shapes,
            np.array([lane.length_m for lane in self._lanes]),
            np.array([lane.is_junction for lane in self._lanes], dtype=bool),
            profile_cache_dir() if cache else None,
        )
        self._curve_index = index_curves(self._chains, self.lane_ids, self.warning_radius_m)

    # ----------------------------------------------------------------- construction
    @classmethod
    def load(cls, net_path: str | Path, warning_radius_m: float | None = None, *, cache: bool = True) -> "RoadMap":
        """Read a ``.net.xml`` / ``.net.xml.gz`` and build its road map.

        Parameters
        ----------
        net_path
            The SUMO network.
        warning_radius_m
            Warning curvature radius R_c (3.2), m; ``None`` for the default
            :data:`csws.standard.DEFAULT_WARNING_RADIUS_M`.
        cache
            Whether to use the profile cache (see :class:`RoadMap`): a network fitted once
            loads in a fraction of the time.

        Raises
        ------
        NetworkError
            If the file is missing, not a SUMO network, or has no lanes.
        """
        net = read_sumo_net(net_path)
        try:
            return cls.from_net(net, warning_radius_m, cache=cache)
        except NetworkError as error:
            raise NetworkError(f"{Path(net_path).name}: {error}") from None

    @classmethod
    def from_net(cls, net: sumolib.net.Net, warning_radius_m: float | None = None, *, cache: bool = True) -> "RoadMap":
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
        continuations = road_continuations(net)
        continuing = _continuing_internal_lanes(sumo_lanes, continuations)
        lanes = [
            _lane_record(lane, float(length), lane.getEdge().getID() in roundabout_edges, lane.getID() in continuing,
                         _continues_into(lane, continuations, continuing, roundabout_edges))
            for lane, length in zip(sumo_lanes, shape_length_m)
        ]  # fmt: skip
        radius = DEFAULT_WARNING_RADIUS_M if warning_radius_m is None else warning_radius_m
        return cls(lanes, xy, vertex_start, successors, _geo_reference(net), radius, cache=cache)

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
        """Bytes held by the map's arrays: vertices, arc lengths, links, road chains and their profiles."""
        arrays = [self._xy, self._vertex_s, self._vertex_start, self._successor_start, self._successor_index]
        arrays += list(self._chains.xy) + [a for p in self._chains.profiles for a in (p.s, p.curvature, p.radius)]
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

    def road_chain(self, lane_id: str) -> tuple[str, ...]:
        """The lanes of the road chain ``lane_id`` belongs to, in driving order (:mod:`csws.roadprofile`)."""
        chain = self._chains.lane_chain[self._lane_index(lane_id)]
        return tuple(self._lanes[i].lane_id for i in self._chains.lanes[chain].tolist())

    def lane_curves(self, lane_id: str) -> tuple[LaneCurve, ...]:
        """The curves of the road (radius <= :attr:`warning_radius_m`) that lie on ``lane_id``, whole
        or in part, in driving order."""
        lane = self._lane_index(lane_id)
        start_s = self._chains.lane_start_s[lane]
        end_s = start_s + self._chains.lane_road_length_m[lane]
        return tuple(
            lane_curve
            for lane_curve in self._curve_index[self._chains.lane_chain[lane]]
            if lane_curve.curve.end_s > start_s and lane_curve.curve.start_s < end_s
        )

    def curves(self, include_junctions: bool = False) -> list[LaneCurve]:
        """The curves of every road, road chain by road chain: the curve index.

        Each curve is listed once, at the lane where it starts, even where it runs on
        through a node into further lanes of its road; the warning reads the same curves
        (:meth:`path_profile`).

        Parameters
        ----------
        include_junctions
            Also list the curves of junction manoeuvres (turns from one road into
            another on internal lanes, roundabouts), left out by default.
        """
        return [
            lane_curve
            for chain_index, lane_curves in enumerate(self._curve_index)
            if include_junctions or not self._chains.is_junction[chain_index]
            for lane_curve in lane_curves
        ]

    def road_position(self, chain: int, s: float) -> tuple[str, float]:
        """The lane id and lane position of arc length ``s`` along road chain ``chain``
        (a :attr:`LaneCurve.chain`, or a chain from :meth:`PathProfile.curve_sources`)."""
        lane, lane_pos_m = self._chains.lane_position(chain, s)
        return self._lanes[lane].lane_id, lane_pos_m

    def curve_shape(self, lane_curve: LaneCurve) -> np.ndarray:
        """The road's polyline from a curve's start (3.4) to its end (3.5), ``(m, 2)``, m."""
        return _shape_between(self._chains.xy[lane_curve.chain], lane_curve.curve.start_s, lane_curve.curve.end_s)

    def curves_geojson(self) -> dict:
        """The curve index (:meth:`curves`) as a GeoJSON FeatureCollection in WGS84 (RFC 7946).

        Each curve is a LineString of the road between its start (3.4) and end (3.5)
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
            lonlat = np.round(self.xy_to_lonlat_many(self.curve_shape(lane_curve)), 6)
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
            write_curve_table(records, stream)
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
        """The road along consecutive lanes: one polyline, with the profile and curves of its road chains.

        A curve that runs across an edge boundary or through a node of its road is one
        curve (3.4-3.5), the same curve the index lists, wherever the path starts. Where
        the path leaves a road (a turn at a junction) it runs on along the next road's
        chain. Internal via lanes missing from ``lane_ids`` are filled in (:meth:`expand_path`).
        """
        path = self.expand_path(lane_ids)
        indices = [self._index[lane_id] for lane_id in path]
        return path_profile(
            self._chains,
            indices,
            path,
            [self._road_shape(i) for i in indices],
            np.array([self._lanes[i].length_m for i in indices]),
            np.array([self._lanes[i].is_junction for i in indices], dtype=bool),
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


