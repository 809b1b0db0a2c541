"""``csws import-opendrive``: an OpenDRIVE file into a SUMO network and, beside it, every lane's exact κ(s).

netconvert builds the network; its options (:data:`NETCONVERT_OPTIONS`):

* ``--output.original-names``: every lane keeps ``origId = "<road>_<lane>"``, which maps it back to the
  OpenDRIVE lane (:mod:`csws.opendrive.exact`);
* ``--opendrive.curve-resolution 1``: lane shapes sampled every 1 m of curve instead of 2 m, so that
  networks without the exact file (and SUMO's own vehicles) follow the design closely;
* csws's defaults: coordinates as authored, no turnarounds at dead ends.

Its messages, warnings included, are kept in ``NAME.netconvert.log`` beside the network. csws then
reads the plan view itself and writes ``NAME.kappa.json``: the road map of the network reads the
curvature from there instead of fitting the shapes (:mod:`csws.opendrive.profiles`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from csws.sumo.netbuild import NetconvertError, netconvert_opendrive

from .exact import exact_lanes, exact_path, write_exact
from .model import OpenDriveError
from .reader import read_opendrive

__all__ = ["NETCONVERT_OPTIONS", "ImportResult", "import_opendrive", "netconvert_log_path"]

NETCONVERT_OPTIONS = ("--output.original-names", "true", "--opendrive.curve-resolution", "1")


@dataclass(frozen=True)
class ImportResult:
    """What an import wrote and found.

    Attributes
    ----------
    net_path, exact_path, log_path
        The network, the exact curvature beside it and netconvert's messages.
    roads, exact_lanes
        How many OpenDRIVE roads were read and how many SUMO lanes got their exact κ(s).
    notes
        What was skipped or does not join in the OpenDRIVE file, and lanes left to the fit.
    convert_s
        Seconds netconvert took.
    """

    net_path: Path
    exact_path: Path
    log_path: Path
    roads: int
    exact_lanes: int
    notes: tuple[str, ...]
    convert_s: float


def netconvert_log_path(net_path: Path) -> Path:
    """Where netconvert's messages go: ``NAME.netconvert.log`` beside the network."""
    return exact_path(net_path).with_name(exact_path(net_path).name.replace(".kappa.json", ".netconvert.log"))


def import_opendrive(xodr_path: str | Path, net_path: str | Path) -> ImportResult:
    """Read ``xodr_path``, netconvert it into ``net_path`` and write the exact κ(s) of its lanes beside it.

    Raises
    ------
    OpenDriveError
        When the file is not OpenDRIVE csws can read, or netconvert cannot import it.
    """
    xodr_path, net_path = Path(xodr_path), Path(net_path)
    opendrive = read_opendrive(xodr_path)
    log_path = netconvert_log_path(net_path)
    started = time.perf_counter()
    try:
        netconvert_opendrive(xodr_path, net_path, (*NETCONVERT_OPTIONS, "--log", str(log_path.resolve())))
    except NetconvertError as error:
        lines = [line for line in str(error).splitlines()[1:] if "error" in line.lower()]
        reason = lines[0] if lines else "netconvert failed"
        raise OpenDriveError(f"netconvert could not import {xodr_path}: {reason}") from None
    convert_s = time.perf_counter() - started
    lanes, lane_notes = exact_lanes(net_path, opendrive)
    written = write_exact(exact_path(net_path), lanes)
    return ImportResult(
        net_path, written, log_path, len(opendrive.roads), len(lanes), (*opendrive.notes, *lane_notes), convert_s
    )
