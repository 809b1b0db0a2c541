"""The JT/T 808 gateway's temporary tracking (``0x8202``): the curves ahead of a slow terminal's vehicle.

On the work thread, after a group is answered, each report of a slow terminal with no tracking
window running is looked at once more: the path ahead from where its fix was placed, long enough
for the warning point of formula (1) plus one regular interval, and its curves, from which
:func:`csws.gateways.jt808.tracking.tracking_window_s` decides whether to ask for 1 s reports
and for how long. Reports of terminals at 1 s, or inside a window, cost nothing here.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence

from csws.ahead.horizon import PathAhead
from csws.gateways.jt808.tracking import CurveAhead, TrackingSettings, tracking_window_s
from csws.standard import Category
from csws.state import SystemState
from csws.warning.latency import fix_age_s, update_period_s

from .answers import WarningService
from .decoding import DecodedQuery
from .placement import Placement

__all__ = ["TrackingPlanner", "curves_ahead"]


def curves_ahead(path: PathAhead) -> list[CurveAhead]:
    """The CPOIs of ``path`` not yet passed, each with the distance to the end of its curve."""
    curve_end_s: dict[str, float] = {}
    for _, end_s, _, _, _, curve_id in path.horizon.parts:
        curve_end_s[curve_id] = max(curve_end_s.get(curve_id, -math.inf), end_s)
    return [
        CurveAhead(distance_m, radius_m, curve_end_s[curve_id] - path.vehicle_s)
        for curve_id, _, distance_m, radius_m, passed in path.cpoi_points()
        if not passed
    ]


class TrackingPlanner:
    """Decides on the work thread how long a report's terminal should be tracked (None: not now).

    Parameters
    ----------
    service
        The warning service whose networks and placements answered the report.
    settings
        When and how to ask for tracking.
    """

    def __init__(self, service: WarningService, settings: TrackingSettings) -> None:
        self.service, self.settings = service, settings

    def window_s(
        self,
        query: DecodedQuery,
        category: Category | None,
        state: SystemState,
        placement: Placement | None,
        intervals_s: Sequence[float],
        fleet: str = "",
    ) -> int | None:
        """The tracking window to ask for after ``query``'s answer (for a vehicle of ``category`` of ``fleet``, its
        system state ``state``, the query placed at ``placement``), s, for a terminal whose regular intervals are
        ``intervals_s``; None when its vehicle is not active on a matched lane or no curve is near. The warning's
        settings are the fleet's (:meth:`service.answers.WarningService.warning_of`).

        The path ahead is the one the engine looks along from the same lane (the most probable path), as far
        as the warning needs at the terminal's period and one regular interval more.
        """
        if placement is None or placement.path_lane_id is None or state != SystemState.ACTIVE or category is None:
            return None
        index = placement.network_index
        engine = self.service.networks[index].engine
        if engine is None or engine.lookahead is None:
            return None
        warning = self.service.warning_of(fleet, index)
        age_s = fix_age_s(query.age_s)
        try:
            reach_period_s = update_period_s(intervals_s, warning) + statistics.median(intervals_s)
            path = engine.lookahead(
                placement.path_lane_id,
                placement.path_lane_pos_m,
                query.speed_kmh,
                category,
                None,
                reach_period_s,
                age_s,
            )
        except KeyError:  # a lane of a network reloaded since: no tracking this time
            return None
        curves = curves_ahead(path)
        return tracking_window_s(curves, query.speed_kmh, category, intervals_s, age_s, warning, self.settings)
