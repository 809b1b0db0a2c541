"""The forward collision warning's settings per fleet, from a settings file (``--fcw-settings FILE``).

Every vehicle's FCW runs with the library's settings for its category
(:meth:`csws.fcw.settings.FcwSettings.for_category`: V_max by category, 4.3.3), with what the file
sets for every fleet (``default``) and then for the vehicle's fleet over them. The file::

    {"format": "csws-fcw-settings/1",
     "default": {"reaction_time_s": 1.4},
     "fleets": {"acme": {"collision_a_req_mps2": 4.0, "max_speed_by_category_mps": {"N": 30.0}}}}

Each block may set any field of :class:`csws.fcw.settings.FcwSettings` except ``max_speed_mps``,
which it sets by category in ``max_speed_by_category_mps``; the library's checks apply (e.g. the
collision threshold at most 0.68 g, 4.5.3). The file is read at start-up, by every worker alike, so
all of them answer a fleet with the same settings; a file that cannot be read, or a block the
library refuses for any category, stops start-up with one line naming the file. The service without
keys is the fleet ``""``, which takes ``default``.
"""

from __future__ import annotations

from dataclasses import fields
from functools import cache
from pathlib import Path
from typing import Any

from csws.fcw.settings import FcwSettings
from csws.standard import Category

from .settings_file import read_settings_file

__all__ = ["FCW_SETTINGS_FORMAT", "FleetFcwSettings"]

FCW_SETTINGS_FORMAT = "csws-fcw-settings/1"
#: What a block may set: every field of FcwSettings but V_max, which it sets per category.
_SETTABLE = frozenset(f.name for f in fields(FcwSettings)) - {"max_speed_mps"}
_BY_CATEGORY = "max_speed_by_category_mps"


def _checked_block(where: str, block: Any) -> dict[str, Any]:
    """One block of the file with its numbers checked; ValueError naming ``where`` otherwise."""
    if not isinstance(block, dict):
        raise ValueError(f"{where}: expected an object of FCW settings")
    unknown = sorted(set(block) - _SETTABLE - {_BY_CATEGORY})
    if unknown:
        raise ValueError(f"{where}: unknown setting(s) {unknown}; known: {sorted(_SETTABLE | {_BY_CATEGORY})}")
    numbers = {name: value for name, value in block.items() if name != _BY_CATEGORY}
    by_category = block.get(_BY_CATEGORY, {})
    if not isinstance(by_category, dict):
        raise ValueError(f"{where}: {_BY_CATEGORY} must map categories to speeds, m/s")
    for name, value in [*numbers.items(), *by_category.items()]:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{where}: {name} must be a number, got {value!r}")
    try:
        parsed = {Category.parse(name): float(value) for name, value in by_category.items()}
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return {**numbers, _BY_CATEGORY: parsed}


class FleetFcwSettings:
    """The FCW settings of each fleet and category.

    Parameters
    ----------
    path
        The settings file; None: the library's settings for each category, for every fleet.

    Raises
    ------
    ValueError
        One line naming the file, when it cannot be read or holds settings the library refuses.
    """

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = None if path is None else Path(path)
        self._default: dict[str, Any] = {}
        self._fleets: dict[str, dict[str, Any]] = {}
        if self.path is not None:
            self._read(self.path)
        for fleet in ["", *self._fleets]:
            for category in Category:
                try:
                    self.of(fleet, category)
                except ValueError as exc:
                    raise ValueError(f"{self.path}: fleet {fleet!r}, category {category.value}: {exc}") from None

    def _read(self, path: Path) -> None:
        """Read and check the file."""
        content = read_settings_file(path, FCW_SETTINGS_FORMAT, "an FCW settings file")
        unknown = sorted(set(content) - {"format", "default", "fleets"})
        fleets = content.get("fleets", {})
        if unknown or not isinstance(fleets, dict):
            raise ValueError(f"{path}: expected format, default and fleets (an object by fleet name), got {unknown}")
        self._default = _checked_block(f"{path}: default", content.get("default", {}))
        self._fleets = {name: _checked_block(f"{path}: fleet {name!r}", block) for name, block in fleets.items()}

    @cache  # noqa: B019 - a few fleets and five categories, for the service's life
    def of(self, fleet: str, category: Category) -> FcwSettings:
        """The settings of a vehicle of ``category`` in ``fleet`` (the same object each time)."""
        own = self._fleets.get(fleet, {})
        speeds = {**self._default.get(_BY_CATEGORY, {}), **own.get(_BY_CATEGORY, {})}
        changes = {
            name: value for block in (self._default, own) for name, value in block.items() if name != _BY_CATEGORY
        }
        if category in speeds:
            changes["max_speed_mps"] = speeds[category]
        return FcwSettings.for_category(category, **changes)
