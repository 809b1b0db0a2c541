"""What a road map shows wrong or doubtful, place by place: the map report a fleet operator sends back to the map.

Every road chain of a network (its lanes stitched into one polyline, :mod:`csws.road.chains`;
junction manoeuvres left out) is read for what the curve index cannot trust or had to mend:

* **artefacts** (``artefact-spike``, ``artefact-fold``, ``artefact-jog``, ``artefact-zigzag``):
  shapes no road has, found on the polyline alone (:func:`csws.curvature.artefacts.polyline_turns`);
  size: the length of the back-and-forth or jog segment (m), a zig-zag's absolute turning (deg);
* **curves at the radius floor** (``floor-curve``): curves of a road's own fit whose smallest radius
  is :data:`csws.curvature.corners.FLOOR_RADIUS_M`, the least a road curve is given (a lane beside
  its road's reference lane has the same curve, its radii moved by the lanes' offset). Such a curve
  is a **real corner** when the polyline turns its way by :data:`csws.curvature.artefacts.CORNER_MIN_DEG`
  or more net over the curve's stretch (its vertices inside and the nearest at or beyond either end turning that
  way, an artefact's vertices counting their net turn only:
  :meth:`~csws.curvature.artefacts.PolylineTurns.net_turn_rad`), the curve no longer than
  :data:`csws.curvature.artefacts.CORNER_SPAN_M`: the road turns there, drawn by too few nodes, or
  nodes too close together, for its radius. Otherwise it is an **artefact**: the fit bent the road
  at the floor where the map draws no corner. Size: the curve's angle (deg);
* **corners mapped by a single node** (``single-node-corner``): a polyline corner of one vertex
  turning :data:`SINGLE_NODE_CORNER_DEG` or more; its radius is not in the map (the index lays an
  arc over it, :func:`csws.curvature.corners.corner_arc`). Size: its turn (deg).

From an OSM import come too, with the way's geometry as far as the extract holds it:

* **ways cut by the extract's border** (``border-cut``) and **dropped ways** (``dropped``), each
  with its reason (:mod:`csws.osm.coverage`). Size: the way's length in the extract (m).

An item names the OSM way (from its edge id: ``-123#4`` is way 123) and the edge and lane; the two
directions of a way and the lanes of an edge show the same artefact, so items of one kind and way
(or edge, on a network of no OSM ways) closer than :data:`SAME_PLACE_M` are one item.

:func:`report_geojson` gives a GeoJSON FeatureCollection (RFC 7946: lon/lat on a geo-referenced
network, else network metres, said in its ``coordinates`` member); artefacts and corners are Points,
floor curves and ways LineStrings. :func:`summary_lines` gives a line per kind for the terminal.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from csws.curvature import Curve, curves_from_profile
from csws.curvature.artefacts import CORNER_MIN_DEG, CORNER_SPAN_M, PolylineTurns, polyline_turns
from csws.curvature.corners import FLOOR_RADIUS_M
from csws.road.export import COORDINATES
from csws.road.roadmap import RoadMap

from .coverage import CUT_BY_BORDER, DroppedRoads, way_id_of_edge

__all__ = [
    "ARTEFACT_KINDS",
    "BORDER_CUT",
    "DROPPED",
    "FLOOR_CURVE",
    "KINDS",
    "SAME_PLACE_M",
    "SINGLE_NODE_CORNER",
    "SINGLE_NODE_CORNER_DEG",
    "ReportItem",
    "dropped_items",
    "network_items",
    "report_geojson",
    "summary_lines",
    "write_report",
]

#: The artefact kinds of the report, by the artefact kinds of :mod:`csws.curvature.artefacts`.
ARTEFACT_KINDS = {kind: f"artefact-{kind}" for kind in ("spike", "fold", "jog", "zigzag")}
#: A curve of the index at the radius floor.
FLOOR_CURVE = "floor-curve"
#: A corner mapped by a single node.
SINGLE_NODE_CORNER = "single-node-corner"
#: A way crossing the extract's border.
BORDER_CUT = "border-cut"
#: A way of the extract the network lacks.
DROPPED = "dropped"
#: Every kind, in the order the summary lists them.
KINDS = (*ARTEFACT_KINDS.values(), FLOOR_CURVE, SINGLE_NODE_CORNER, BORDER_CUT, DROPPED)

#: A corner of one node turning this much or more is listed, degrees: OSM maps an ordinary curve by nodes 5-30 m
#: apart, each turning a few degrees (R 300 m turns 4 degrees over 20 m); 30 degrees at one node is a radius
#: under 40 m over such chords, which the map does not give.
SINGLE_NODE_CORNER_DEG = 30.0
#: Items of one kind and way (or edge) closer than this are one item, m: the lanes of an edge and the two
#: directions of a way lie a lane width or two apart.
SAME_PLACE_M = 10.0
#: A curve whose smallest radius is within this of the floor is at the floor, m.
FLOOR_TOLERANCE_M = 1e-6
#: Decimals of the coordinates: lon/lat to 1e-6 degrees (0.1 m), network metres to the centimetre.
_DECIMALS = {True: 6, False: 2}


@dataclass(frozen=True)
class ReportItem:
    """One thing the report lists.

    Attributes
    ----------
    kind
        One of :data:`KINDS`.
    points
        Where it is: one point (a Point) or several (a LineString), ``(k, 2)``, in the report's coordinates
        (lon/lat on a geo-referenced network or from an OSM extract, else network metres).
    size, unit
        Its size and the unit of it (``m`` or ``deg``; see the module).
    reason
        What is wrong or doubtful, in words.
    way_id
        The OSM way, None where the edge id names none.
    edge_id, lane_id
        The edge and lane it lies on ("" for a way the network lacks).
    real_corner
        For a floor curve, whether it is a real corner (else an artefact); None for other kinds.
    """

    kind: str
    points: np.ndarray
    size: float
    unit: str
    reason: str
    way_id: int | None = None
    edge_id: str = ""
    lane_id: str = ""
    real_corner: bool | None = None


@dataclass(frozen=True)
class _Found:
    """An item found on a road chain, before it is placed: kind, arc lengths along the chain (one for a point,
    two for the stretch of a curve), size, unit, reason, and for a floor curve whether it is a real corner."""

    kind: str
    s: tuple[float, ...]
    size: float
    unit: str
    reason: str
    real_corner: bool | None = None


def _artefacts_found(turns: PolylineTurns) -> list[_Found]:
    """The artefacts of a polyline, each at the middle of its vertices."""
    found = []
    for artefact in turns.artefacts:
        unit = "deg" if artefact.kind == "zigzag" else "m"
        what = "absolute turning" if unit == "deg" else "segment"
        found.append(
            _Found(
                ARTEFACT_KINDS[artefact.kind],
                ((artefact.start_s + artefact.end_s) / 2.0,),
                artefact.size,
                unit,
                f"map artefact: {artefact.kind} ({what} {artefact.size:.2f} {unit}); "
                "the curve index takes its net turn only",
            )
        )
    return found


def _single_node_corners(turns: PolylineTurns) -> list[_Found]:
    """The corners of one vertex turning :data:`SINGLE_NODE_CORNER_DEG` or more."""
    return [
        _Found(
            SINGLE_NODE_CORNER,
            (corner.start_s,),
            abs(math.degrees(corner.turn_rad)),
            "deg",
            f"corner of {abs(math.degrees(corner.turn_rad)):.0f} deg mapped by a single node: its radius is not in "
            "the map (more nodes along the bend would give it)",
        )
        for corner in turns.corners()
        if corner.start_s == corner.end_s and abs(math.degrees(corner.turn_rad)) >= SINGLE_NODE_CORNER_DEG
    ]


def _is_real_corner(turns: PolylineTurns, curve: Curve) -> bool:
    """Whether the polyline turns the curve's way by :data:`~csws.curvature.artefacts.CORNER_MIN_DEG` or more net
    over the curve's stretch, the curve no longer than :data:`~csws.curvature.artefacts.CORNER_SPAN_M`."""
    side = 1.0 if curve.direction == "left" else -1.0
    net_deg = math.degrees(turns.net_turn_rad(curve.start_s, curve.end_s, side))
    return net_deg >= CORNER_MIN_DEG and curve.end_s - curve.start_s <= CORNER_SPAN_M


def _floor_curves(turns: PolylineTurns, curves: Iterable[Curve]) -> list[_Found]:
    """The curves at the radius floor, each judged a real corner or an artefact."""
    found = []
    for curve in curves:
        if curve.min_radius_m > FLOOR_RADIUS_M + FLOOR_TOLERANCE_M:
            continue
        real = _is_real_corner(turns, curve)
        judged = "a real corner drawn by too few nodes for its radius" if real else "an artefact: no such turn mapped"
        found.append(
            _Found(
                FLOOR_CURVE,
                (curve.start_s, curve.end_s),
                curve.angle_deg,
                "deg",
                f"curve of {curve.angle_deg:.0f} deg at the radius floor of {FLOOR_RADIUS_M:.0f} m: {judged}",
                real,
            )
        )
    return found


def _along(xy: np.ndarray, s: tuple[float, ...]) -> np.ndarray:
    """The point at arc length ``s[0]`` of polyline ``xy``, or its stretch from ``s[0]`` to ``s[1]``, ``(k, 2)``."""
    vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    if len(s) == 1:
        at = np.array(s)
    else:
        inside = vertex_s[(vertex_s > s[0]) & (vertex_s < s[1])]
        at = np.concatenate(([s[0]], inside, [s[1]]))
    return np.column_stack((np.interp(at, vertex_s, xy[:, 0]), np.interp(at, vertex_s, xy[:, 1])))


def _edge_lane(road_map: RoadMap, chain: int, s: float) -> str:
    """The lane of a road chain at arc length ``s``: an edge's lane, the nearer one where ``s`` lies on an internal
    lane (the chord across a junction), whose id names a node, not a way."""
    chains = road_map.chains
    members = chains.lanes[chain].tolist()
    position = members.index(chains.lane_at(chain, s))
    lane = members[position]
    if road_map.lane(road_map.lane_ids[lane]).function == "internal" and len(members) > 1:
        start_s = float(chains.lane_start_s[lane])
        end_s = start_s + float(chains.lane_road_length_m[lane])
        nearer_end = position + 1 < len(members) and (end_s - s < s - start_s or position == 0)
        lane = members[position + 1 if nearer_end else position - 1]
    return road_map.lane_ids[lane]


def _own_floor_curves(road_map: RoadMap, chain: int) -> list[Curve]:
    """The curves of a road chain's own fit (none where its lanes borrow their road's), if it reaches the radius
    floor: a lane moved beside another has its radii moved by the lanes' offset (:mod:`csws.road.sharing`)."""
    fitted = road_map.chains.fitted[chain]
    if fitted is None or float(fitted.radius.min()) > FLOOR_RADIUS_M + FLOOR_TOLERANCE_M:
        return []
    return curves_from_profile(fitted, road_map.warning_radius_m, policy=road_map.warning_policy)


def _chain_found(road_map: RoadMap, chain: int) -> list[_Found]:
    """Everything the report lists on one road chain."""
    turns = polyline_turns(road_map.chains.xy[chain])
    if len(turns.turn_rad) == 0:
        return []
    floor_curves = _floor_curves(turns, _own_floor_curves(road_map, chain))
    return _artefacts_found(turns) + _single_node_corners(turns) + floor_curves


def network_items(road_map: RoadMap) -> list[ReportItem]:
    """The artefacts, floor curves and single-node corners of every road chain of a road map (see the module),
    one item per place, in the report's coordinates (lon/lat on a geo-referenced map, else network metres)."""
    chains = road_map.chains
    placed: list[tuple[ReportItem, np.ndarray]] = []
    for chain, xy in enumerate(chains.xy):
        if chains.is_junction[chain]:
            continue
        for found in _chain_found(road_map, chain):
            points = _along(xy, found.s)
            lane_id = _edge_lane(road_map, chain, found.s[0])
            edge_id = road_map.lane(lane_id).edge_id
            item = ReportItem(
                found.kind,
                points,
                found.size,
                found.unit,
                found.reason,
                way_id_of_edge(edge_id),
                edge_id,
                lane_id,
                found.real_corner,
            )
            placed.append((item, points[len(points) // 2]))
    kept = _one_per_place(placed)
    if road_map.has_projection:
        kept = [_with_points(item, road_map.xy_to_lonlat_many(item.points)) for item in kept]
    return kept


def _with_points(item: ReportItem, points: np.ndarray) -> ReportItem:
    """``item`` at ``points``."""
    return ReportItem(
        item.kind, points, item.size, item.unit, item.reason, item.way_id, item.edge_id, item.lane_id, item.real_corner
    )


def _one_per_place(placed: Sequence[tuple[ReportItem, np.ndarray]]) -> list[ReportItem]:
    """The items, but of those of one kind and way (or edge) closer than :data:`SAME_PLACE_M`, the first only."""
    kept: list[ReportItem] = []
    seen: dict[tuple[str, int | str], list[np.ndarray]] = {}
    for item, middle in placed:
        near = seen.setdefault((item.kind, item.way_id if item.way_id is not None else item.edge_id), [])
        if any(math.dist(middle, other) < SAME_PLACE_M for other in near):
            continue
        near.append(middle)
        kept.append(item)
    return kept


def dropped_items(dropped: DroppedRoads, way_lonlat: Mapping[int, np.ndarray]) -> list[ReportItem]:
    """The ways an import dropped or found cut by the extract's border (:mod:`csws.osm.coverage`), each at its
    nodes in the extract (``way_lonlat``: way id -> lon/lat ``(k, 2)``; a way of no such node is left out)."""
    items = []
    for way in dropped.ways_listed:
        points = np.asarray(way_lonlat.get(way.way_id, np.zeros((0, 2))), dtype=float)
        if len(points) == 0:
            continue
        items.append(
            ReportItem(
                BORDER_CUT if way.reason == CUT_BY_BORDER else DROPPED,
                points,
                way.length_m,
                "m",
                f"{way.highway} way: {way.reason}",
                way.way_id,
            )
        )
    return items


def _feature(index: int, item: ReportItem, decimals: int) -> dict[str, Any]:
    """One item as a GeoJSON Feature."""
    points = np.round(item.points, decimals)
    geometry = (
        {"type": "Point", "coordinates": points[0].tolist()}
        if len(points) == 1
        else {"type": "LineString", "coordinates": points.tolist()}
    )
    properties: dict[str, Any] = {
        "kind": item.kind,
        "way_id": item.way_id,
        "edge_id": item.edge_id,
        "lane_id": item.lane_id,
        "size": round(item.size, 2),
        "unit": item.unit,
        "reason": item.reason,
    }
    if item.real_corner is not None:
        properties["real_corner"] = item.real_corner
    return {"type": "Feature", "id": index, "geometry": geometry, "properties": properties}


def report_geojson(items: Sequence[ReportItem], lonlat: bool, **members: Any) -> dict[str, Any]:
    """The items as a GeoJSON FeatureCollection; ``lonlat`` says whether their points are lon/lat (RFC 7946) or
    network metres (said in the ``coordinates`` member); ``members`` are added to the collection (a source, an
    attribution)."""
    decimals = _DECIMALS[lonlat]
    return {
        "type": "FeatureCollection",
        "coordinates": COORDINATES[lonlat],
        **members,
        "summary": {kind: count for kind, count in _counts(items).items() if count},
        "features": [_feature(index, item, decimals) for index, item in enumerate(items)],
    }


def write_report(items: Sequence[ReportItem], lonlat: bool, path: Path, **members: Any) -> Path:
    """Write :func:`report_geojson` of the items to ``path``."""
    with open(path, "w", encoding="utf-8") as stream:
        json.dump(report_geojson(items, lonlat, **members), stream, separators=(",", ":"))
        stream.write("\n")
    return path


def _counts(items: Iterable[ReportItem]) -> Counter[str]:
    """How many items of each kind, every kind of :data:`KINDS` present."""
    counts = Counter({kind: 0 for kind in KINDS})
    counts.update(item.kind for item in items)
    return counts


def summary_lines(items: Sequence[ReportItem]) -> list[str]:
    """One line per kind: how many, and the largest size (floor curves: how many real corners and artefacts)."""
    lines = []
    for kind, count in _counts(items).items():
        sizes = [item for item in items if item.kind == kind]
        detail = ""
        if kind == FLOOR_CURVE:
            real = sum(bool(item.real_corner) for item in sizes)
            detail = f" ({real} real corners, {count - real} artefacts)"
        elif sizes:
            largest = max(sizes, key=lambda item: item.size)
            detail = f" (largest {largest.size:.2f} {largest.unit})"
        lines.append(f"map report: {kind:<19} {count:>6}{detail}")
    return lines
