"""Reads a SUMO network: its lanes as records, and their shapes and links as arrays.

:func:`read_sumo_net` reads a ``.net.xml`` (or ``.net.xml.gz``) with its internal lanes
and turns every failure into :class:`NetworkError`; :func:`net_lanes` takes from it what
the road map keeps: a :class:`Lane` record per lane (normal and internal lanes; pedestrian
crossings and walking areas are left out), the vertices of all lane shapes back to back,
the lanes reached from each lane's end, and the network's geo-reference.

Each lane also says whether the road continues through it (:attr:`Lane.continues_road`,
:attr:`Lane.continues_into`), from :func:`csws.road.continuations.road_continuations`, and whether
it belongs to a roundabout: the road map fits road chains and tells junction manoeuvres
from curves of the road with them.
"""

from __future__ import annotations

import xml.sax
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np
import sumolib

from csws.errors import CswsError
from csws.road.continuations import road_continuations

__all__ = ["Lane", "NetLanes", "NetworkError", "net_lanes", "projection_net", "read_sumo_net"]

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


class NetworkError(ValueError, CswsError):
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
        continuation: :func:`csws.road.continuations.road_continuations`) rather than turning
        into another road. Always False for normal lanes.
    continues_into
        The lane this lane's road continues on ("" where the road ends or turns, on a
        junction turn and on a roundabout): the next lane of its road chain
        (:mod:`csws.road.chains`).
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
class NetLanes:
    """What a road map keeps of a SUMO network.

    Attributes
    ----------
    lanes
        The lanes' records, in network order.
    xy
        Vertices of all lane shapes back to back, ``(n, 2)``, m.
    vertex_start
        Offset of each lane's first vertex in ``xy`` and ``n`` at the end.
    successors
        For each lane, the indices of the lanes a vehicle can drive onto from its end.
    geo
        A bare sumolib net carrying only the network's location (geo-reference).
    """

    lanes: list[Lane]
    xy: np.ndarray
    vertex_start: np.ndarray
    successors: list[list[int]]
    geo: sumolib.net.Net


def net_lanes(net: sumolib.net.Net) -> NetLanes:
    """The lanes of a sumolib net read with ``withInternal=True``, copied into records and
    arrays so that the sumolib objects can be freed.

    Raises
    ------
    NetworkError
        If the network has no lanes, or a lane's shape is broken.
    """
    sumo_lanes = [lane for edge in net.getEdges() if edge.getFunction() in _KEPT_FUNCTIONS for lane in edge.getLanes()]
    if not sumo_lanes:
        raise NetworkError("the network has no lanes with a shape")
    for lane in sumo_lanes:
        _check_shape(lane)
    vertex_start = np.concatenate(([0], np.cumsum([len(lane.getShape()) for lane in sumo_lanes]))).astype(np.int64)
    xy = np.array(list(chain.from_iterable(lane.getShape() for lane in sumo_lanes)), dtype=float).reshape(-1, 2)
    shape_length_m = vertex_arc_length(xy, vertex_start)[vertex_start[1:] - 1]
    index = {lane.getID(): i for i, lane in enumerate(sumo_lanes)}
    roundabout_edges = _roundabout_edge_ids(net)
    continuations = road_continuations(net)
    continuing = _continuing_internal_lanes(sumo_lanes, continuations)
    lanes = [
        _lane_record(
            lane,
            float(length),
            lane.getEdge().getID() in roundabout_edges,
            lane.getID() in continuing,
            _continues_into(lane, continuations, continuing, roundabout_edges),
        )
        for lane, length in zip(sumo_lanes, shape_length_m, strict=False)
    ]
    successors = [_successor_ids(lane, index) for lane in sumo_lanes]
    return NetLanes(lanes, xy, vertex_start, successors, _geo_reference(net))


def vertex_arc_length(xy: np.ndarray, vertex_start: np.ndarray) -> np.ndarray:
    """Arc length of every vertex along its own lane, for lanes stored back to back in ``xy``."""
    step_m = np.concatenate(([0.0], np.hypot(*np.diff(xy, axis=0).T)))
    step_m[vertex_start[:-1]] = 0.0
    cumulative_m = np.cumsum(step_m)
    lane_of_vertex = np.repeat(np.arange(len(vertex_start) - 1), np.diff(vertex_start))
    return cumulative_m - cumulative_m[vertex_start[:-1]][lane_of_vertex]


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


def _continuing_internal_lanes(
    sumo_lanes: Sequence[sumolib.net.lane.Lane], continuations: frozenset[tuple[str, str]]
) -> set[str]:
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
    lane: sumolib.net.lane.Lane,
    continuations: frozenset[tuple[str, str]],
    continuing: set[str],
    roundabout: frozenset[str],
) -> str:
    """The lane a sumolib lane's road continues on, "" where it ends or turns (:attr:`Lane.continues_into`).

    From a normal lane: the lane reached by its connection into the edge that continues
    the road (:func:`csws.road.continuations.road_continuations`), the connection's internal lane
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
    return projection_net(getattr(net, "_location", {}))


def projection_net(location: Mapping[str, str]) -> sumolib.net.Net:
    """A bare sumolib net of a SUMO network's ``<location>`` attributes (``netOffset``, ``convBoundary``,
    ``origBoundary``, ``projParameter``; SUMO's defaults for those missing): its coordinate conversions only."""
    geo = sumolib.net.Net()
    geo.setLocation(
        location.get("netOffset", "0.00,0.00"),
        location.get("convBoundary", "0.00,0.00,0.00,0.00"),
        location.get("origBoundary", "0.00,0.00,0.00,0.00"),
        location.get("projParameter", "!"),
    )
    return geo
