"""The forward collision warning of queries that carry a ``forward_target``: the library's
:func:`csws.fcw.physics.evaluate_fcw` and :func:`csws.fcw.physics.next_fcw_states`, once for all such queries
of a round, written into their answers' ``fcw``.

The target is the one the on-board unit's sensor selected (GB/T 33577 4.4.3); the service
keeps no FCW state between queries, so the state is taken from each query's speed alone
(the hysteresis of Figure 2 is the on-board unit's).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from csws.fcw.physics import ACTIVE, FCW_STATES, STANDBY, FcwSettings, evaluate_fcw, next_fcw_states
from csws.standard import kmh_to_mps

from .decoding import DecodedQuery

__all__ = ["fcw_answers"]


def _finite(value: float) -> float | None:
    """A number for JSON: None where it is infinite."""
    return value if math.isfinite(value) else None


def fcw_answers(queries: Sequence[DecodedQuery], settings: FcwSettings = FcwSettings()) -> list[dict | None]:
    """The contract's FcwAnswer of each query, None for those without a forward_target."""
    rows = [i for i, query in enumerate(queries) if query.forward_target is not None]
    answers: list[dict | None] = [None] * len(queries)
    if not rows:
        return answers
    targets = [queries[i].forward_target for i in rows]
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
    for k, i in enumerate(rows):
        answers[i] = {
            "state": FCW_STATES[states[k]].value,
            "level": int(levels[k]),
            "ttc_s": _finite(float(batch.ttc_s[k])),
            "ettc_s": _finite(float(batch.ettc_s[k])),
            "a_req_mps2": _finite(float(batch.a_req_mps2[k])),
        }
    return answers
