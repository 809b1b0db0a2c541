"""What an OSM import kept of the extract's motor roads, and what it dropped.

netconvert names each edge after the way it came from (``123``, ``-123``, ``123#2``), so
the ways of an extract that left no edge are known, with their ``highway`` value and
length. Of the ways whose road type lets a kept vehicle class drive, those missing are
roads closed to it by their own tags (``hgv=no``), roads outside the largest connected
part of the network, short ways inside joined junctions, or roads netconvert could not
type; the import prints them so that none goes unnoticed.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field

__all__ = ["DroppedRoads", "LOSS_WARNING_SHARE", "dropped_roads", "way_id_of_edge"]

#: Above this share of the extract's motor-road length dropped, the import warns.
LOSS_WARNING_SHARE = 0.01


@dataclass(frozen=True)
class DroppedRoads:
    """The motor ways of an extract that left no edge in its network.

    Attributes
    ----------
    motor_km
        Length of every drivable motor way of the extract, km.
    by_highway
        ``highway value -> (ways, km)`` of the dropped ones.
    """

    motor_km: float
    by_highway: dict[str, tuple[int, float]] = field(default_factory=dict)

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
        """What was dropped, one line per highway value (longest first), and a warning line
        when more than :data:`LOSS_WARNING_SHARE` of the length was."""
        lines = [
            f"dropped {ways} {value} way(s), {km:.2f} km"
            for value, (ways, km) in sorted(self.by_highway.items(), key=lambda item: -item[1][1])
        ]
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


def dropped_roads(motor_ways: dict[int, tuple[str, float]], edge_ids: Iterable[str]) -> DroppedRoads:
    """The motor ways (``way id -> (highway value, length in m)``) that left none of ``edge_ids``."""
    kept = {way for way in map(way_id_of_edge, edge_ids) if way is not None}
    by_highway: dict[str, list[float]] = defaultdict(lambda: [0, 0.0])
    for way, (value, length_m) in motor_ways.items():
        if way not in kept:
            by_highway[value][0] += 1
            by_highway[value][1] += length_m / 1000.0
    total_km = sum(length_m for _, length_m in motor_ways.values()) / 1000.0
    return DroppedRoads(total_km, {value: (int(ways), km) for value, (ways, km) in by_highway.items()})
