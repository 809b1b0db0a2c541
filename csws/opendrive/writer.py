"""Writes OpenDRIVE roads made of lines, arcs and clothoids, with lane sections, grade and superelevation.

The tests and the accuracy benchmark describe roads by their design (:class:`RoadSpec`): the plan view
as pieces of known curvature, the lanes by width. Each geometry's start point and heading are those the
reader's own integration finds at the end of the piece before, so the written plan view joins.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

from .geometry import geometry_poses
from .model import Geometry

__all__ = ["PlanPiece", "SectionSpec", "RoadSpec", "line", "arc", "spiral", "opendrive_text", "write_opendrive"]


@dataclass(frozen=True)
class PlanPiece:
    """A plan-view piece: its length, m, and signed curvature at start and end, 1/m (positive turning left)."""

    length_m: float
    start_curvature: float = 0.0
    end_curvature: float = 0.0

    @property
    def kind(self) -> str:
        """The OpenDRIVE element that describes it."""
        if self.start_curvature != self.end_curvature:
            return "spiral"
        return "arc" if self.start_curvature else "line"


def line(length_m: float) -> PlanPiece:
    """A straight of ``length_m``."""
    return PlanPiece(length_m)


def arc(length_m: float, radius_m: float) -> PlanPiece:
    """An arc of ``length_m`` and signed radius (positive turning left)."""
    return PlanPiece(length_m, 1.0 / radius_m, 1.0 / radius_m)


def spiral(length_m: float, start_curvature: float, end_curvature: float) -> PlanPiece:
    """A clothoid from one signed curvature to another."""
    return PlanPiece(length_m, start_curvature, end_curvature)


@dataclass(frozen=True)
class SectionSpec:
    """A lane section from ``s_m``: lane widths outward from the reference line, left (ids 1, 2...) and right
    (ids -1, -2...), m."""

    s_m: float = 0.0
    left_widths_m: tuple[float, ...] = (3.5,)
    right_widths_m: tuple[float, ...] = (3.5,)


@dataclass(frozen=True)
class RoadSpec:
    """One road: id, start pose, plan view, lane sections, constant grade (m/m) and superelevation (rad).

    ``elevation_poly`` and ``superelevation_poly``, when given, are the cubics (a, b, c, d) in s of the
    elevation (m) and the superelevation (rad) over the whole road instead of the constants.
    ``predecessor`` and ``successor`` join the road's start to another road's end and its end to another
    road's start, each lane to the lane of the same id there.
    """

    road_id: str
    pieces: tuple[PlanPiece, ...]
    x_m: float = 0.0
    y_m: float = 0.0
    heading_rad: float = 0.0
    sections: tuple[SectionSpec, ...] = field(default_factory=lambda: (SectionSpec(),))
    grade: float = 0.0
    superelevation_rad: float = 0.0
    lefthand: bool = False
    elevation_poly: tuple[float, float, float, float] | None = None
    superelevation_poly: tuple[float, float, float, float] | None = None
    predecessor: str | None = None
    successor: str | None = None

    @property
    def length_m(self) -> float:
        """The road's length, m."""
        return sum(piece.length_m for piece in self.pieces)

    def geometries(self) -> list[Geometry]:
        """The plan view: each piece placed where the one before ends."""
        geometries: list[Geometry] = []
        s, x, y, hdg = 0.0, self.x_m, self.y_m, self.heading_rad
        for piece in self.pieces:
            params: tuple[tuple[str, float], ...] = ()
            if piece.kind == "arc":
                params = (("curvature", piece.start_curvature),)
            elif piece.kind == "spiral":
                params = (("curvStart", piece.start_curvature), ("curvEnd", piece.end_curvature))
            geometry = Geometry(s, x, y, hdg, piece.length_m, piece.kind, params)
            geometries.append(geometry)
            end = geometry_poses(geometry, step=0.01)
            s, x, y, hdg = geometry.end_s, float(end.x[-1]), float(end.y[-1]), float(end.hdg[-1])
        return geometries

    def end_pose(self) -> tuple[float, float, float]:
        """Where the reference line ends: x, y (m) and heading (rad), for a road to go on from there."""
        end = geometry_poses(self.geometries()[-1], step=0.01)
        return float(end.x[-1]), float(end.y[-1]), float(end.hdg[-1])

    def lane_ids(self, section: SectionSpec) -> set[int]:
        """The lane ids of one of its lane sections (left positive, right negative)."""
        return set(range(1, len(section.left_widths_m) + 1)) | set(range(-len(section.right_widths_m), 0))


def _add(parent: ElementTree.Element, tag: str, **attributes: object) -> ElementTree.Element:
    """A child element with attributes written as text (floats with full precision)."""
    return ElementTree.SubElement(
        parent, tag, {key: repr(float(v)) if isinstance(v, float) else str(v) for key, v in attributes.items()}
    )


def _lanes(parent: ElementTree.Element, section: SectionSpec, before: set[int], after: set[int]) -> None:
    """One ``<laneSection>`` with its left, centre and right lanes, each linked to the lane of its id ``before``
    (in the road it comes from) and ``after`` (in the road it goes on to) where that has one."""
    element = _add(parent, "laneSection", s=float(section.s_m))
    for side, widths, sign in (("left", section.left_widths_m, 1), ("right", section.right_widths_m, -1)):
        if not widths:
            continue
        holder = _add(element, side)
        for number, width in enumerate(widths, start=1):
            lane_id = sign * number
            lane = _add(holder, "lane", id=lane_id, type="driving", level="false")
            if lane_id in before | after:
                link = _add(lane, "link")
                for tag, ids in (("predecessor", before), ("successor", after)):
                    if lane_id in ids:
                        _add(link, tag, id=lane_id)
            _add(lane, "width", sOffset=0.0, a=float(width), b=0.0, c=0.0, d=0.0)
        if side == "left":
            _add(_add(element, "center"), "lane", id=0, type="none", level="false")


def _road(root: ElementTree.Element, spec: RoadSpec, roads: dict[str, RoadSpec]) -> None:
    """One ``<road>`` element; ``roads`` by id, for the lanes its links join."""
    road = _add(root, "road", id=spec.road_id, length=float(spec.length_m), junction="-1")
    if spec.lefthand:
        road.set("rule", "LHT")
    before: set[int] = set()
    after: set[int] = set()
    if spec.predecessor or spec.successor:
        link = _add(road, "link")
        if spec.predecessor:
            _add(link, "predecessor", elementType="road", elementId=spec.predecessor, contactPoint="end")
            before = roads[spec.predecessor].lane_ids(roads[spec.predecessor].sections[-1])
        if spec.successor:
            _add(link, "successor", elementType="road", elementId=spec.successor, contactPoint="start")
            after = roads[spec.successor].lane_ids(roads[spec.successor].sections[0])
    plan_view = _add(road, "planView")
    for g in spec.geometries():
        geometry = _add(plan_view, "geometry", s=g.s, x=g.x, y=g.y, hdg=g.hdg, length=float(g.length))
        _add(geometry, g.kind, **{name: value for name, value in g.params})
    elevation = spec.elevation_poly or (0.0, spec.grade, 0.0, 0.0)
    superelevation = spec.superelevation_poly or (spec.superelevation_rad, 0.0, 0.0, 0.0)
    for profile, tag, cubic in (
        ("elevationProfile", "elevation", elevation),
        ("lateralProfile", "superelevation", superelevation),
    ):
        _add(_add(road, profile), tag, s=0.0, **{name: float(v) for name, v in zip("abcd", cubic, strict=True)})
    lanes = _add(road, "lanes")
    for index, section in enumerate(spec.sections):
        first, last = index == 0, index == len(spec.sections) - 1
        _lanes(lanes, section, before if first else set(), after if last else set())


def opendrive_text(roads: Sequence[RoadSpec]) -> str:
    """The OpenDRIVE 1.6 document of ``roads``."""
    root = ElementTree.Element("OpenDRIVE")
    _add(root, "header", revMajor=1, revMinor=6, name="csws", version="1.0")
    by_id = {spec.road_id: spec for spec in roads}
    for spec in roads:
        _road(root, spec, by_id)
    ElementTree.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ElementTree.tostring(root, encoding="unicode") + "\n"


def write_opendrive(path: str | Path, roads: Sequence[RoadSpec]) -> Path:
    """Write ``roads`` to ``path`` as an ``.xodr`` file."""
    path = Path(path)
    path.write_text(opendrive_text(roads), encoding="utf-8")
    return path
