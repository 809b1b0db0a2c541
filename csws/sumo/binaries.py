"""Where the SUMO programs are: the ones the ``eclipse-sumo`` wheel installs.

Users need neither SUMO on PATH nor a SUMO_HOME of their own: the wheel that
``pip install csws`` brings carries ``sumo`` and ``netconvert``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from csws.errors import CswsError


class SumoNotFoundError(RuntimeError, CswsError):
    """A SUMO program is not where the eclipse-sumo package puts it."""


#: SUMO's options for a run that prints nothing but errors: no step log, no warnings, no duration log.
QUIET_OPTIONS = ("--no-step-log", "true", "--no-warnings", "true", "--duration-log.disable", "true")


def sumo_home() -> Path:
    """SUMO_HOME of the installed eclipse-sumo package."""
    try:
        import sumo  # the eclipse-sumo wheel
    except ImportError as exc:  # pragma: no cover - a broken install
        raise SumoNotFoundError("the eclipse-sumo package is not installed: pip install eclipse-sumo") from exc
    return Path(sumo.SUMO_HOME)


def sumo_binary(name: str) -> Path:
    """Path of the SUMO program ``name`` (``"sumo"``, ``"netconvert"``, ...) from eclipse-sumo."""
    executable = name + (".exe" if sys.platform == "win32" else "")
    path = sumo_home() / "bin" / executable
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise SumoNotFoundError(f"{name} is not in the eclipse-sumo package at {path}")
    return path
