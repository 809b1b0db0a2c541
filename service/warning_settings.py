"""The curve warning's latency and release settings per fleet, from a settings file (``--warning-settings FILE``).

A service answers every fleet with its own settings (``CSWS_UPDATE_PERIOD_S``, ``CSWS_LEARN_UPDATE_PERIOD``,
``CSWS_RELEASE_*``, the table of docs/service.md). A fleet whose vehicles report in a way those do not fit
pins its own here: its terminals' fixed reporting period with learning off, a longer cap on the period
learnt, or a release rule that holds a level longer. The file::

    {"format": "csws-warning-settings/1",
     "fleets": {"acme": {"update_period_s": 10.0, "learn_update_period": false, "release_hold_s": 2.0}}}

A fleet's block may set the fields of :data:`SETTABLE` (of :class:`csws.warning.settings.WarningSettings`);
the others (the warning speeds, the system's delay, formula (1)'s g) are the service's for every fleet, as
the look-ahead of a served network is shared by its fleets. The library's checks apply. The file is read once
at start-up, before the workers start, so all of them answer a fleet alike; a file that cannot be read, or a
block the library refuses, stops start-up with one line naming the file. A fleet not in the file, and the
service without keys (the fleet ``""``, which the file cannot name), take the service's settings.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from csws.warning.settings import WarningSettings

from .settings_file import read_settings_file

__all__ = ["SETTABLE", "WARNING_SETTINGS_FORMAT", "FleetWarningSettings"]

WARNING_SETTINGS_FORMAT = "csws-warning-settings/1"
#: What a fleet's block may set, and whether each is a yes/no (else a number).
SETTABLE = {
    "update_period_s": False,
    "learn_update_period": True,
    "max_update_period_s": False,
    "release_margin_kmh": False,
    "release_hold_s": False,
    "release_hold_intervals": False,
}


class FleetWarningSettings:
    """The curve warning's settings of each fleet: the service's, with what the file pins for the fleet.

    Parameters
    ----------
    service
        The service's warning settings (every fleet's where the file sets nothing).
    path
        The settings file; None: the service's settings for every fleet.

    Raises
    ------
    ValueError
        One line naming the file, when it cannot be read or sets what the library refuses.
    """

    def __init__(self, service: WarningSettings, path: str | Path | None = None) -> None:
        self.service = service
        self.path = None if path is None else Path(path)
        self._fleets: dict[str, WarningSettings] = {}
        if self.path is not None:
            self._fleets = _read(self.path, service)

    def of(self, fleet: str) -> WarningSettings:
        """The settings of ``fleet``'s vehicles (the same object each time)."""
        return self._fleets.get(fleet, self.service)


def _read(path: Path, service: WarningSettings) -> dict[str, WarningSettings]:
    """Each fleet's settings from the file at ``path``; ValueError naming it where it cannot be taken."""
    content = read_settings_file(path, WARNING_SETTINGS_FORMAT, "a warning settings file")
    unknown = sorted(set(content) - {"format", "fleets"})
    fleets = content.get("fleets", {})
    if unknown or not isinstance(fleets, dict):
        raise ValueError(f"{path}: expected format and fleets (an object by fleet name), got {unknown or fleets!r}")
    if "" in fleets:
        raise ValueError(f"{path}: a fleet's block needs the fleet's name (the service without keys takes its own)")
    return {str(name): _fleet_settings(f"{path}: fleet {name!r}", block, service) for name, block in fleets.items()}


def _fleet_settings(where: str, block: Any, service: WarningSettings) -> WarningSettings:
    """The service's settings with one fleet's block over them; ValueError naming ``where`` otherwise."""
    if not isinstance(block, dict):
        raise ValueError(f"{where}: expected an object of warning settings")
    unknown = sorted(set(block) - set(SETTABLE))
    if unknown:
        raise ValueError(f"{where}: unknown setting(s) {unknown}; known: {sorted(SETTABLE)}")
    changes: dict[str, Any] = {}
    for name, value in block.items():
        is_flag = isinstance(value, bool)
        if SETTABLE[name] != is_flag or not (is_flag or isinstance(value, int | float)):
            kind = "true or false" if SETTABLE[name] else "a number"
            raise ValueError(f"{where}: {name} must be {kind}, got {value!r}")
        try:
            changes[name] = value if is_flag else float(value)
        except OverflowError:
            raise ValueError(f"{where}: {name} is too large a number") from None
    try:
        return replace(service, **changes)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
