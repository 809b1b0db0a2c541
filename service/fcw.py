"""The forward collision warning of queries that carry a ``forward_target``, and the HMI of both systems.

A ``forward_target`` is answered by the library's :func:`csws.fcw.physics.evaluate_fcw` and
:func:`csws.fcw.state.next_fcw_states`, once for the queries of a round with the same settings.
The target is the one the on-board unit's sensor selected (GB/T 33577 4.4.3); the service keeps no
FCW state for such queries, so the state is taken from each query's speed alone (the hysteresis of
Figure 2 is the on-board unit's). Queries with ``objects`` are answered with state kept between
queries (:mod:`service.fcw_objects`).

:func:`combined_hmi` is the answer's ``hmi`` where both systems answer: the most urgent warning of
the two (docs/service.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from csws.fcw.physics import evaluate_fcw
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, FCW_STATES, STANDBY, next_fcw_states
from csws.standard import Level, kmh_to_mps
from csws.warning.rules import HmiHint

from .decoding import DecodedQuery

__all__ = ["FCW_HMI_HINTS", "finite", "fcw_answers", "combined_hmi"]

#: How to present the FCW's levels (4.5.2, Table 4 of 4.10.1): the preliminary warning visual and
#: amber, the collision warning visual, red and flashing, with a tone of its own (4.5.2: told apart
#: from other warnings, as the curve warning's).
FCW_HMI_HINTS = {
    1: HmiHint(visual="forward-collision-amber", audible=None),
    2: HmiHint(visual="forward-collision-red-flashing", audible="collision-tone"),
}


def finite(value: float) -> float | None:
    """A number for JSON: None where it is infinite or NaN."""
    return value if math.isfinite(value) else None


def combined_hmi(curve_level: int, fcw_level: int) -> HmiHint:
    """The hint of the more urgent warning: FCW level 2, then curve level 2, then FCW level 1, then curve level 1.

    A collision warning is the most urgent (4.10.1, Table 4: its tone louder than every other
    warning of the vehicle); a curve's level 2 asks the driver to brake now, before a preliminary
    collision warning that only draws attention; at equal levels the FCW's, whose time to act is
    the shorter (seconds to a vehicle ahead against a curve's warning distance).
    """
    if fcw_level > 0 and fcw_level >= curve_level:
        return FCW_HMI_HINTS[fcw_level]
    return HmiHint.for_level(Level(curve_level))


def fcw_answers(queries: Sequence[DecodedQuery], settings: Sequence[FcwSettings]) -> list[dict | None]:
    """The contract's FcwAnswer of each query with a forward_target (and no objects), with its ``settings``;
    None for the others."""
    answers: list[dict | None] = [None] * len(queries)
    groups: dict[int, list[int]] = {}
    for i, query in enumerate(queries):
        if query.forward_target is not None and query.objects is None:
            groups.setdefault(id(settings[i]), []).append(i)
    for rows in groups.values():
        for i, answer in zip(rows, _target_answers([queries[i] for i in rows], settings[rows[0]]), strict=True):
            answers[i] = answer
    return answers


def _target_answers(queries: Sequence[DecodedQuery], settings: FcwSettings) -> list[dict]:
    """The FcwAnswer of queries with a forward_target, all with ``settings``."""
    rows = list(range(len(queries)))
    targets = [target for target in (query.forward_target for query in queries) if target is not None]
    column = lambda name: np.array([getattr(target, name) for target in targets])  # noqa: E731
    states = next_fcw_states(
        np.full(len(rows), STANDBY),
        kmh_to_mps(np.array([queries[i].speed_kmh for i in rows])),
        np.ones(len(rows), dtype=bool),
        column("measured"),
        settings,
    )
    batch = evaluate_fcw(
        column("subject_accel_mps2"),
        column("range_m"),
        column("range_rate_mps"),
        column("target_accel_mps2"),
        column("driver_braking"),
        settings,
    )
    levels = np.where(states == ACTIVE, batch.level, 0)
    return [
        {
            "state": FCW_STATES[states[k]].value,
            "level": int(levels[k]),
            "ttc_s": finite(float(batch.ttc_s[k])),
            "ettc_s": finite(float(batch.ettc_s[k])),
            "a_req_mps2": finite(float(batch.a_req_mps2[k])),
            "target_id": None,
            "clearance_m": float(targets[k].range_m),
        }
        for k in rows
    ]
