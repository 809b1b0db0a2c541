"""The parts of an ASAM OpenDRIVE road that csws reads: plan view, lanes, elevation and superelevation.

Every length is in metres, every angle in radians, curvature in 1/m positive turning left
(counter-clockwise), as OpenDRIVE defines them. The lateral coordinate t points left of
the reference line; lanes left of it have positive ids, lanes right of it negative ids.
"""

from __future__ import annotations

from dataclasses import dataclass

from csws.errors import CswsError

__all__ = ["OpenDriveError", "Cubic", "Geometry", "Lane", "LaneSection", "Road", "record_in_force"]


class OpenDriveError(ValueError, CswsError):
    """An OpenDRIVE file csws cannot read: not XML, not OpenDRIVE, or a road without what it needs."""


@dataclass(frozen=True)
class Cubic:
    """One record of a cubic polynomial in ``ds = s - s0``: a + b ds + c ds^2 + d ds^3.

    Used for ``<elevation>``, ``<superelevation>``, ``<laneOffset>`` (s0 along the road) and
    ``<width>`` (s0 the record's ``sOffset`` plus its lane section's start).
    """

    s0: float
    a: float
    b: float
    c: float
    d: float

    def value(self, s: float) -> float:
        """The polynomial at road position ``s``."""
        ds = s - self.s0
        return self.a + ds * (self.b + ds * (self.c + ds * self.d))

    def slope(self, s: float) -> float:
        """Its first derivative with respect to s at ``s``."""
        ds = s - self.s0
        return self.b + ds * (2.0 * self.c + 3.0 * ds * self.d)

    def bend(self, s: float) -> float:
        """Its second derivative with respect to s at ``s``."""
        return 2.0 * self.c + 6.0 * (s - self.s0) * self.d

    @property
    def is_constant(self) -> bool:
        """Whether it does not change along s."""
        return self.b == 0.0 and self.c == 0.0 and self.d == 0.0


@dataclass(frozen=True)
class Geometry:
    """One ``<geometry>`` record of a ``<planView>``.

    Attributes
    ----------
    s, x, y, hdg, length
        Its start along the reference line, start point, start heading and length.
    kind
        ``"line"``, ``"arc"``, ``"spiral"``, ``"poly3"`` or ``"paramPoly3"``.
    params
        The kind's attributes: ``curvature`` (arc); ``curvStart``, ``curvEnd`` (spiral);
        ``a``, ``b``, ``c``, ``d`` (poly3); ``aU`` ... ``dV`` and ``pRange`` as 1.0 for
        ``arcLength`` and 0.0 for ``normalized`` (paramPoly3).
    """

    s: float
    x: float
    y: float
    hdg: float
    length: float
    kind: str
    params: tuple[tuple[str, float], ...] = ()

    def param(self, name: str) -> float:
        """The value of one of the kind's attributes (0 when absent, as OpenDRIVE's defaults)."""
        return dict(self.params).get(name, 0.0)

    @property
    def end_s(self) -> float:
        """Where it ends along the reference line."""
        return self.s + self.length


@dataclass(frozen=True)
class Lane:
    """One lane of a lane section: its id (left positive, right negative), type and width records."""

    lane_id: int
    lane_type: str
    widths: tuple[Cubic, ...]

    def width(self, s: float) -> Cubic | None:
        """The width record in force at road position ``s`` (None before the first)."""
        return record_in_force(self.widths, s)


@dataclass(frozen=True)
class LaneSection:
    """One ``<laneSection>``: where it starts and ends along the road, and its lanes (centre lane left out)."""

    s: float
    end_s: float
    lanes: tuple[Lane, ...]

    def lane(self, lane_id: int) -> Lane | None:
        """The lane with this id, None where the section has none."""
        return next((lane for lane in self.lanes if lane.lane_id == lane_id), None)


@dataclass(frozen=True)
class Road:
    """One ``<road>``: its plan view, lanes and profiles.

    Attributes
    ----------
    road_id, length, junction
        Its id, length and the junction it belongs to (``"-1"`` for none).
    lefthand
        Whether traffic keeps left on it (``rule="LHT"``): then the left lanes drive along s.
    geometries
        The plan view, in order of s.
    sections
        The lane sections, in order of s.
    lane_offsets, elevations, superelevations
        The ``<laneOffset>``, ``<elevation>`` and ``<superelevation>`` records, in order of s.
    """

    road_id: str
    length: float
    junction: str
    lefthand: bool
    geometries: tuple[Geometry, ...]
    sections: tuple[LaneSection, ...]
    lane_offsets: tuple[Cubic, ...] = ()
    elevations: tuple[Cubic, ...] = ()
    superelevations: tuple[Cubic, ...] = ()

    def lane_offset(self, s: float) -> Cubic | None:
        """The lane-offset record in force at ``s``."""
        return record_in_force(self.lane_offsets, s)

    def elevation(self, s: float) -> Cubic | None:
        """The elevation record in force at ``s``."""
        return record_in_force(self.elevations, s)

    def superelevation(self, s: float) -> Cubic | None:
        """The superelevation record in force at ``s``."""
        return record_in_force(self.superelevations, s)

    def drives_along_s(self, lane_id: int) -> bool:
        """Whether traffic on lane ``lane_id`` drives in the direction of increasing s."""
        return (lane_id > 0) if self.lefthand else (lane_id < 0)


def record_in_force(records: tuple[Cubic, ...], s: float) -> Cubic | None:
    """The last record starting at or before ``s`` (records sorted by start)."""
    current = None
    for record in records:
        if record.s0 <= s + 1e-9:
            current = record
        else:
            break
    return current
