"""What an OSM import kept of the extract's motor roads, and what it dropped, way by way with the reason.

netconvert names each edge after the way it came from (``123``, ``-123``, ``123#2``), so
the ways of an extract that left no edge are known, with their ``highway`` value and
length. Each is dropped for one of :data:`REASONS`: its road type lets none of the kept
vehicle classes drive (:data:`CLOSED_TYPE`); it runs across the extract's border, some of its
nodes missing (:data:`CUT_BY_BORDER`); or, its type open to them, it left no edge all the same
(:data:`NOT_IN_NETWORK`: closed to them by its own tags such as ``hgv=no``, outside the largest
connected part of the network, a short way inside a joined junction). Ways cut by the border
are listed whether or not part of them was kept: the network ends there. The import prints a
line per reason and writes every way (:func:`write_dropped_ways`), so that none goes unnoticed.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "CLOSED_TYPE",
    "CUT_BY_BORDER",
    "NOT_IN_NETWORK",
    "REASONS",
    "DroppedRoads",
    "DroppedWay",
    "LOSS_WARNING_SHARE",
    "dropped_roads",
    "way_id_of_edge",
    "write_dropped_ways",
]

#: A way dropped because its road type lets none of the kept vehicle classes drive.
CLOSED_TYPE = "road type closed to the kept vehicle classes"
#: A way crossing the extract's border (some of its nodes missing); kept in part or dropped.
CUT_BY_BORDER = "cut by the extract border"
#: A way open by its type that left no edge: closed by its own tags, not connected, or inside a joined junction.
NOT_IN_NETWORK = "open to the kept classes by type, but not in the network (own tags, not connected, in a junction)"
#: Every reason, in the order the import prints them.
REASONS = (CLOSED_TYPE, CUT_BY_BORDER, NOT_IN_NETWORK)

#: Above this share of the extract's motor-road length dropped, the import warns.
LOSS_WARNING_SHARE = 0.01


@dataclass(frozen=True)
class DroppedWay:
    """One way of the extract the network lacks (or, cut by the border, holds only in part): its OSM id,
    ``highway`` value, length as far as its nodes are in the extract (m), and one of :data:`REASONS`."""

    way_id: int
    highway: str
    length_m: float
    reason: str


@dataclass(frozen=True)
class DroppedRoads:
    """The motor ways of an extract that left no edge in its network.

    Attributes
    ----------
    motor_km
        Length of every drivable motor way of the extract, km.
    by_highway
        ``highway value -> (ways, km)`` of the dropped ones open to the kept classes by their type.
    ways_listed
        Every way dropped or cut by the border, with its reason (:class:`DroppedWay`).
    """

    motor_km: float
    by_highway: dict[str, tuple[int, float]] = field(default_factory=dict)
    ways_listed: tuple[DroppedWay, ...] = ()

    @property
    def ways(self) -> int:
        """Number of ways dropped."""
        return sum(ways for ways, _ in self.by_highway.values())

    @property
    def km(self) -> float:
        """Length dropped, km."""
        return sum(km for _, km in self.by_highway.values())

    @property
    def share(self) -> float:
        """Share of the motor-road length dropped (0 for an extract without motor roads)."""
        return self.km / self.motor_km if self.motor_km > 0 else 0.0

    def lines(self) -> list[str]:
        """What was dropped of the roads open to the kept classes, one line per highway value (longest first),
        a line per reason of every way listed, and a warning line when more than :data:`LOSS_WARNING_SHARE`
        of the length open to the kept classes was dropped."""
        lines = [
            f"dropped {ways} {value} way(s), {km:.2f} km"
            for value, (ways, km) in sorted(self.by_highway.items(), key=lambda item: -item[1][1])
        ]
        for reason in REASONS:
            listed = [way for way in self.ways_listed if way.reason == reason]
            if listed:
                km = sum(way.length_m for way in listed) / 1000.0
                lines.append(f"{reason}: {len(listed)} way(s), {km:.2f} km")
        if self.share > LOSS_WARNING_SHARE:
            lines.append(
                f"warning: {self.km:.1f} of {self.motor_km:.1f} km of drivable roads ({self.share:.1%}) "
                "are not in the network"
            )
        return lines


def way_id_of_edge(edge_id: str) -> int | None:
    """The OSM way an edge came from (``-123#4`` -> 123); None for an edge of no way."""
    text = edge_id.lstrip("-").split("#", 1)[0]
    return int(text) if text.isdigit() else None


def dropped_roads(
    motor_ways: dict[int, tuple[str, float]],
    edge_ids: Iterable[str],
    closed: dict[int, tuple[str, float]] | None = None,
    cut: Iterable[int] = (),
) -> DroppedRoads:
    """The motor ways open to the kept classes (``way id -> (highway value, length in m)``) that left none of
    ``edge_ids``, with every way listed by reason: the ``closed`` ones (their type lets no kept class drive) and
    those of either crossing the extract's border (``cut``)."""
    kept = {way for way in map(way_id_of_edge, edge_ids) if way is not None}
    cut = set(cut)
    by_highway: dict[str, list[float]] = defaultdict(lambda: [0, 0.0])
    listed = []
    for way, (value, length_m) in motor_ways.items():
        if way in cut:
            listed.append(DroppedWay(way, value, length_m, CUT_BY_BORDER))
        if way not in kept:
            by_highway[value][0] += 1
            by_highway[value][1] += length_m / 1000.0
            if way not in cut:
                listed.append(DroppedWay(way, value, length_m, NOT_IN_NETWORK))
    for way, (value, length_m) in (closed or {}).items():
        listed += [DroppedWay(way, value, length_m, CLOSED_TYPE)] + [
            DroppedWay(way, value, length_m, CUT_BY_BORDER)
        ] * (way in cut)
    total_km = sum(length_m for _, length_m in motor_ways.values()) / 1000.0
    return DroppedRoads(
        total_km,
        {value: (int(ways), km) for value, (ways, km) in by_highway.items()},
        tuple(sorted(listed, key=lambda way: (REASONS.index(way.reason), way.way_id))),
    )


def write_dropped_ways(dropped: DroppedRoads, path: Path) -> Path:
    """Write every way listed (dropped, or cut by the border) as CSV: ``way_id,highway,length_m,reason``."""
    with open(path, "w", encoding="utf-8", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(("way_id", "highway", "length_m", "reason"))
        for way in dropped.ways_listed:
            writer.writerow((way.way_id, way.highway, f"{way.length_m:.1f}", way.reason))
    return path
