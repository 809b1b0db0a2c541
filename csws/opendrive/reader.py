"""Reads an ASAM OpenDRIVE file (``.xodr``) into :class:`csws.opendrive.model.Road` objects, with notes.

What csws does not use (signals, objects, junction details, lane attributes other than
width...) is skipped; an element inside ``<planView>``, ``<lanes>``, a lane section or a
lane that csws does not know is skipped *with a note*, because it may carry geometry csws
then ignores. Plan views are checked: a geometry that does not start where the previous one
ends (a gap over :data:`JOIN_TOLERANCE_M`, or an ``s`` that is not the previous ``s`` plus its
length, e.g. a spiral of inconsistent length) is reported with the road id. A file that is not
XML or not OpenDRIVE, or a road without a number it needs, raises :class:`OpenDriveError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

from .geometry import geometry_poses
from .model import Cubic, Geometry, Lane, LaneSection, OpenDriveError, Road

__all__ = ["JOIN_TOLERANCE_M", "OpenDriveFile", "read_opendrive", "parse_opendrive"]

#: Largest gap between consecutive plan-view geometries taken as joined, m.
JOIN_TOLERANCE_M = 0.01

_GEOMETRY_KINDS = {
    "line": (),
    "arc": ("curvature",),
    "spiral": ("curvStart", "curvEnd"),
    "poly3": ("a", "b", "c", "d"),
    "paramPoly3": ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV"),
}
#: Elements of a road csws reads or knowingly passes over (no note for them).
_ROAD_CHILDREN = {"link", "type", "planView", "elevationProfile", "lateralProfile", "lanes", "objects", "signals"}
_ROAD_CHILDREN |= {"surface", "railroad", "userData", "include", "dataQuality"}
_LANE_CHILDREN = {"link", "width", "roadMark", "speed", "material", "access", "height", "rule", "border", "visibility"}
_LANE_CHILDREN |= {"userData", "include", "dataQuality"}


@dataclass(frozen=True)
class OpenDriveFile:
    """A read OpenDRIVE file: its roads and the notes on what was skipped or does not join."""

    roads: tuple[Road, ...]
    notes: tuple[str, ...]


def read_opendrive(path: str | Path) -> OpenDriveFile:
    """Read an ``.xodr`` file.

    Raises
    ------
    OpenDriveError
        When the file cannot be read, is not XML or not OpenDRIVE, or a road lacks a number it needs.
    """
    try:
        text = Path(path).read_bytes()
    except OSError as error:
        raise OpenDriveError(f"cannot read {path}: {error.strerror or error}") from None
    return parse_opendrive(text, source=str(path))


def parse_opendrive(text: str | bytes, source: str = "<text>") -> OpenDriveFile:
    """Read OpenDRIVE XML text (see :func:`read_opendrive`)."""
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise OpenDriveError(f"{source} is not well-formed XML: {error}") from None
    if root.tag != "OpenDRIVE":
        raise OpenDriveError(f"{source} is not OpenDRIVE: its root element is <{root.tag}>")
    notes: list[str] = []
    try:
        roads = tuple(_road(element, notes) for element in root.iter("road"))
    except OpenDriveError as error:
        raise OpenDriveError(f"{source}: {error}") from None
    if not roads:
        raise OpenDriveError(f"{source} has no <road>")
    return OpenDriveFile(roads, tuple(notes))


def _number(element: ElementTree.Element, name: str, where: str, default: float | None = None) -> float:
    """A finite number attribute, ``default`` when absent (OpenDriveError when absent without one, or not a number)."""
    text = element.get(name)
    if text is None:
        if default is None:
            raise OpenDriveError(f"{where}: <{element.tag}> has no {name!r}")
        return default
    try:
        value = float(text)
    except ValueError:
        raise OpenDriveError(f"{where}: <{element.tag}> {name}={text!r} is not a number") from None
    if not math.isfinite(value):
        raise OpenDriveError(f"{where}: <{element.tag}> {name}={text!r} is not finite")
    return value


def _cubics(parent: ElementTree.Element | None, tag: str, where: str, s_name: str = "s", s_base: float = 0.0):
    """The cubic records ``<tag s a b c d>`` under ``parent``, sorted by start."""
    if parent is None:
        return ()
    records = [
        Cubic(s_base + _number(e, s_name, where), *(_number(e, name, where, 0.0) for name in "abcd"))
        for e in parent.findall(tag)
    ]
    return tuple(sorted(records, key=lambda record: record.s0))


def _road(element: ElementTree.Element, notes: list[str]) -> Road:
    """One ``<road>``."""
    road_id = element.get("id")
    if road_id is None:
        raise OpenDriveError("a <road> has no 'id'")
    where = f"road {road_id}"
    for child in element:
        if child.tag not in _ROAD_CHILDREN:
            notes.append(f"{where}: <{child.tag}> skipped")
    plan_view = element.find("planView")
    if plan_view is None:
        raise OpenDriveError(f"{where} has no <planView>")
    geometries = _geometries(plan_view, where, notes)
    length = _number(element, "length", where)
    _check_joins(geometries, where, notes)
    lateral = element.find("lateralProfile")
    lanes = element.find("lanes")
    return Road(
        road_id=road_id,
        length=length,
        junction=element.get("junction", "-1"),
        lefthand=element.get("rule", "RHT").upper() == "LHT",
        geometries=geometries,
        sections=_sections(lanes, length, where, notes),
        lane_offsets=_cubics(lanes, "laneOffset", where),
        elevations=_cubics(element.find("elevationProfile"), "elevation", where),
        superelevations=_cubics(lateral, "superelevation", where),
    )


def _geometries(plan_view: ElementTree.Element, where: str, notes: list[str]) -> tuple[Geometry, ...]:
    """The ``<geometry>`` records of a plan view, in order of s."""
    geometries = []
    for record in plan_view:
        if record.tag != "geometry":
            notes.append(f"{where}: <planView> <{record.tag}> skipped")
            continue
        s, x, y, hdg, length = (_number(record, name, where) for name in ("s", "x", "y", "hdg", "length"))
        kinds = [child for child in record if child.tag in _GEOMETRY_KINDS]
        for child in record:
            if child.tag not in _GEOMETRY_KINDS:
                notes.append(f"{where}: <geometry s={s:g}> <{child.tag}> skipped")
        if len(kinds) != 1:
            raise OpenDriveError(f"{where}: <geometry s={s:g}> has {len(kinds)} shapes, not one")
        kind = kinds[0]
        params = [(name, _number(kind, name, where, 0.0)) for name in _GEOMETRY_KINDS[kind.tag]]
        if kind.tag == "paramPoly3":
            params.append(("pRange", 1.0 if kind.get("pRange", "arcLength") == "arcLength" else 0.0))
        if length < 0:
            raise OpenDriveError(f"{where}: <geometry s={s:g}> has a negative length")
        geometries.append(Geometry(s, x, y, hdg, length, kind.tag, tuple(params)))
    if not geometries:
        raise OpenDriveError(f"{where}: the <planView> has no <geometry>")
    return tuple(sorted(geometries, key=lambda geometry: geometry.s))


def _check_joins(geometries: tuple[Geometry, ...], where: str, notes: list[str]) -> None:
    """Note each geometry whose start is not where the one before ends (position or s)."""
    for before, after in zip(geometries[:-1], geometries[1:], strict=True):
        end = geometry_poses(before)
        gap_m = math.hypot(float(end.x[-1]) - after.x, float(end.y[-1]) - after.y)
        if abs(before.end_s - after.s) > JOIN_TOLERANCE_M:
            notes.append(
                f"{where}: the {before.kind} at s={before.s:g} is {before.length:g} m long but the next geometry "
                f"starts at s={after.s:g} (inconsistent length)"
            )
        if gap_m > JOIN_TOLERANCE_M:
            notes.append(f"{where}: the {before.kind} at s={before.s:g} ends {gap_m:.3f} m from the next geometry")


def _sections(
    lanes: ElementTree.Element | None, length: float, where: str, notes: list[str]
) -> tuple[LaneSection, ...]:
    """The lane sections of a road, each with its end (the next one's start, or the road's length)."""
    if lanes is None:
        return ()
    for child in lanes:
        if child.tag not in ("laneOffset", "laneSection"):
            notes.append(f"{where}: <lanes> <{child.tag}> skipped")
    elements = sorted(lanes.findall("laneSection"), key=lambda e: _number(e, "s", where))
    starts = [_number(e, "s", where) for e in elements]
    ends = [*starts[1:], length]
    return tuple(_section(e, s, end, where, notes) for e, s, end in zip(elements, starts, ends, strict=True))


def _section(element: ElementTree.Element, s: float, end_s: float, where: str, notes: list[str]) -> LaneSection:
    """One ``<laneSection>``: its left and right lanes with their width records."""
    lanes = []
    for side in element:
        if side.tag not in ("left", "center", "right"):
            notes.append(f"{where}: <laneSection s={s:g}> <{side.tag}> skipped")
            continue
        for lane in side.findall("lane"):
            lane_id = int(_number(lane, "id", where))
            for child in lane:
                if child.tag not in _LANE_CHILDREN:
                    notes.append(f"{where}: lane {lane_id} <{child.tag}> skipped")
            if lane.find("border") is not None and lane.find("width") is None:
                notes.append(f"{where}: lane {lane_id} at s={s:g} has <border> and no <width>: taken as 0 m wide")
            if lane_id != 0:
                widths = _cubics(lane, "width", where, s_name="sOffset", s_base=s)
                lanes.append(Lane(lane_id, lane.get("type", "none"), widths))
    return LaneSection(s, end_s, tuple(sorted(lanes, key=lambda lane: lane.lane_id)))
