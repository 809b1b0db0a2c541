"""The co-simulation as SUMO's floating car data with each vehicle's warning: ``csws cosim --fcd FILE``.

The file has the shape of SUMO's ``--fcd-output``, so what reads SUMO's FCD (sumolib's
``sumolib.xml.parse_fast``, ``traceExporter.py``, a GIS import) reads it::

    <fcd-export>
        <timestep time="12.30">
            <vehicle id="car7" x="1043.25" y="8.61" angle="68.93" type="car" speed="27.78" pos="143.37"
                     lane="curve_0" csws_state="active" csws_level="1"/>
        </timestep>
    </fcd-export>

Each evaluated vehicle (SUMO's own export also lists vehicles of classes outside the standard)
carries SUMO's attributes ``id``, ``x``, ``y`` (network m), ``angle`` (degrees, 0 north,
clockwise), ``type``, ``speed`` (m/s), ``pos`` (lane position, m) and ``lane``, with SUMO's
default precision (2 decimals), and the system's: ``csws_state`` and ``csws_level`` (the curve
speed warning, 0 to 2), with ``--systems fcw`` ``fcw_level``, and on a geo-referenced network
``lon`` and ``lat`` (degrees, WGS84, 7 decimals; SUMO's ``--fcd-output.geo`` would put them in
``x`` and ``y`` instead).

A timestep's ``time`` is SUMO's: SUMO labels the state a step leaves with the time the step
began, while the time series and the events (``time_s``) carry the time SUMO reports after
the step, one step length later; so a vehicle's FCD at ``time`` is its time-series row at
``time + step length``, and the file matches SUMO's own ``--fcd-output`` of the same scenario
timestep for timestep. A ``<timestep>`` is written for every step the time series keeps
(``--timeseries-every``), with one write, as the run goes; the closing tag when the run ends,
also when it is interrupted or SUMO stops, so the file parses; a run killed outright leaves
every timestep before the kill but no closing tag.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .evaluators import FleetWarnings
from .records import StepValues, write_whole

__all__ = ["FcdWriter"]

_HEADER = '<?xml version="1.0" encoding="UTF-8"?>\n<fcd-export>\n'
_FOOTER = "</fcd-export>\n"


class FcdWriter:
    """Appends one ``<timestep>`` of every evaluated vehicle at a time to an FCD file (see the module).

    Parameters
    ----------
    path
        The file; its folder is made when missing.
    step_length_s
        SUMO's step length, s: a step's ``time`` is its ``time_s`` less this (see the module).
    """

    def __init__(self, path: Path, step_length_s: float) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.step_length_s = step_length_s
        # SUMO writes times with 2 decimals, more for a step length that needs them (a multiple of 1 ms).
        self._time_decimals = 2 if abs(step_length_s * 100 - round(step_length_s * 100)) < 1e-9 else 3
        self._names: dict[str, str] = {}
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        write_whole(self._fd, _HEADER)

    def append(self, step: StepValues, warnings: FleetWarnings, fcw_level: Sequence[int] | None = None) -> None:
        """Write the step's ``<timestep>``: every vehicle of ``step`` with its warnings (and FCW level)."""
        fleet = step.fleet
        if fleet.type_id is None or fleet.angle_deg is None:
            raise ValueError("an FCD timestep needs the vehicles' types and angles: read the step with headings")
        extra = [""] * len(fleet.vehicle_id)
        if fcw_level is not None:
            extra = [f' fcw_level="{level}"' for level in fcw_level]
        if step.geo is not None:
            extra = [
                f'{more} lon="{lon:.7f}" lat="{lat:.7f}"'
                for more, lon, lat in zip(extra, step.lon, step.lat, strict=True)
            ]
        quoted = self._quoted
        lines = [f'    <timestep time="{fleet.time_s - self.step_length_s:.{self._time_decimals}f}">\n']
        lines += [
            f'        <vehicle id={quoted(vehicle_id)} x="{x_m:.2f}" y="{y_m:.2f}" angle="{angle_deg:.2f}"'
            f' type={quoted(type_id)} speed="{speed_mps:.2f}" pos="{pos_m:.2f}" lane={quoted(lane_id)}'
            f' csws_state="{state}" csws_level="{level}"{more}/>\n'
            for vehicle_id, x_m, y_m, angle_deg, type_id, speed_mps, pos_m, lane_id, state, level, more in zip(
                fleet.vehicle_id,
                step.x_m,
                step.y_m,
                fleet.angle_deg.tolist(),
                fleet.type_id,
                fleet.speed_mps.tolist(),
                step.lane_pos_m,
                fleet.lane_id,
                warnings.state,
                warnings.level,
                extra,
                strict=True,
            )
        ]
        lines.append("    </timestep>\n")
        write_whole(self._fd, "".join(lines))

    def _quoted(self, name: str) -> str:
        """``name`` as a quoted XML attribute value, quoted once per name (ids, types and lanes recur)."""
        found = self._names.get(name)
        if found is None:
            found = self._names[name] = quoteattr(name)
        return found

    def close(self) -> None:
        """Write the closing tag and close the file."""
        if self._fd >= 0:
            write_whole(self._fd, _FOOTER)
            os.close(self._fd)
            self._fd = -1
