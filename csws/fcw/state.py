"""The forward collision warning's system state (GB/T 33577-2017 4.3, Figure 2): off, standby, active or fault.

Codes into :data:`FCW_STATES`, computed by one rule for one vehicle's floats and bools
(:func:`fcw_state_code`) and for a fleet's arrays (:func:`next_fcw_states`) alike (:mod:`csws.fcw.numeric`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from csws.fcw.numeric import isfinite, where
from csws.fcw.settings import FcwSettings
from csws.state import SystemState

__all__ = ["FCW_STATES", "OFF", "STANDBY", "ACTIVE", "FAULT", "fcw_state_code", "next_fcw_states"]

#: The system states by code (4.3.2; fault as CSWS's, :class:`csws.state.SystemState`): ``FCW_STATES[code]``.
FCW_STATES = (SystemState.OFF, SystemState.STANDBY, SystemState.ACTIVE, SystemState.FAULT)
OFF, STANDBY, ACTIVE, FAULT = range(4)


def fcw_state_code(
    previous: Any, speed_mps: Any, switched_on: Any, measured: Any, forward_gear: Any, settings: FcwSettings
) -> Any:
    """The system state after one update (4.3, Figure 2) as a code into :data:`FCW_STATES`, for
    floats and bools (an int) or arrays.

    Off while switched off; fault while the forward sensor gives no valid measurement (4.4.5:
    the driver is told; it clears with the next good one, as CSWS's faults do); else active
    between V_min and V_max in a forward gear (4.3.2: reverse or park is standby), standby
    otherwise, the band widened by the hysteresis delta for a system that was active or in fault
    (so that a short fault does not drop an active system to standby).
    """
    margin = where(previous >= ACTIVE, settings.hysteresis_mps, 0.0)
    inside = (speed_mps >= settings.min_speed_mps - margin) & (speed_mps <= settings.max_speed_mps + margin)
    state = where(inside & forward_gear, ACTIVE, STANDBY)
    state = where(measured & isfinite(speed_mps), state, FAULT)
    return where(switched_on, state, OFF)


def next_fcw_states(
    previous: ArrayLike,
    speed_mps: ArrayLike,
    switched_on: ArrayLike,
    measured: ArrayLike,
    settings: FcwSettings = FcwSettings(),
    forward_gear: ArrayLike = True,
) -> np.ndarray:
    """The system state of many subject vehicles after one update (4.3, Figure 2), as codes into
    :data:`FCW_STATES` (arrays ``(n,)``): :func:`fcw_state_code` on arrays."""
    codes = fcw_state_code(
        np.asarray(previous, dtype=np.int8),
        np.asarray(speed_mps, dtype=float),
        np.asarray(switched_on, dtype=bool),
        np.asarray(measured, dtype=bool),
        np.asarray(forward_gear, dtype=bool),
        settings,
    )
    return np.asarray(codes, dtype=np.int8)
