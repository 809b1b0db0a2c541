"""Check the curve extractor against the ground truth of the bundled test tracks.

Every track in ``networks/`` comes with a truth file written by its generator from the
constructed geometry (never measured back). This module loads each network, stitches
its route into one path, extracts the curves and compares every constant-radius part
with the truth curve it should be: start (3.4) and end (3.5) within a tolerance in
metres, radius within a relative tolerance, and no curve where the truth has none.
This is ``csws networks verify``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from csws.road.roadmap import RoadMap

__all__ = ["CurveCheck", "VerificationReport", "verify_networks", "verify_network"]


@dataclass(frozen=True)
class CurveCheck:
    """One truth curve of one network against what the extractor found.

    Attributes
    ----------
    network
        The network's name.
    curve
        The standard's name of the curve ("curve 1", "curve 2"), or "extra" for a curve
        the extractor found where the truth has none.
    truth_start_s, truth_end_s, truth_radius_m
        The truth along the route, m (NaN for an extra curve).
    found_start_s, found_end_s, found_radius_m
        The extractor's part matched to it, m (NaN when none was found).
    passed
        Whether start and end are within the tolerance and the radius within its.
    """

    network: str
    curve: str
    truth_start_s: float
    truth_end_s: float
    truth_radius_m: float
    found_start_s: float
    found_end_s: float
    found_radius_m: float
    passed: bool

    @property
    def start_error_m(self) -> float:
        """Found minus true start, m."""
        return self.found_start_s - self.truth_start_s

    @property
    def end_error_m(self) -> float:
        """Found minus true end, m."""
        return self.found_end_s - self.truth_end_s


@dataclass(frozen=True)
class VerificationReport:
    """All checks of a verification run."""

    checks: tuple[CurveCheck, ...]
    tolerance_m: float
    radius_tolerance: float

    @property
    def passed(self) -> bool:
        """Whether every check passed (and there was something to check)."""
        return bool(self.checks) and all(check.passed for check in self.checks)

    def as_table(self) -> str:
        """A fixed-width table, one line per check, and a verdict line."""
        header = (
            f"{'network':<24} {'curve':<8} {'start err m':>11} {'end err m':>10} {'R true':>7} {'R found':>8}  result"
        )
        lines = [header, "-" * len(header)]
        for c in self.checks:
            lines.append(
                f"{c.network:<24} {c.curve:<8} {c.start_error_m:>+11.3f} {c.end_error_m:>+10.3f} "
                f"{c.truth_radius_m:>7.1f} {c.found_radius_m:>8.2f}  {'ok' if c.passed else 'FAIL'}"
            )
        failed = sum(not c.passed for c in self.checks)
        worst_m = max((max(abs(c.start_error_m), abs(c.end_error_m)) for c in self.checks if c.passed), default=0.0)
        lines.append(
            f"{len(self.checks) - failed}/{len(self.checks)} curves within {self.tolerance_m:g} m and "
            f"{self.radius_tolerance:.0%} of radius (worst passing error {worst_m:.3f} m): "
            + ("PASS" if self.passed else "FAIL")
        )
        return "\n".join(lines)


def verify_network(
    net_file: Path, truth: dict, tolerance_m: float = 1.0, radius_tolerance: float = 0.01
) -> list[CurveCheck]:
    """Compare the curves extracted along one network's route with its truth."""
    road_map = RoadMap.load(net_file)
    path = road_map.path_profile([lane["lane"] for lane in truth["lanes"]])
    parts = [part for curve in path.curves(road_map.warning_radius_m) for part in curve.parts]
    checks, matched = [], set()
    for curve in truth["curves"]:
        index = min(range(len(parts)), key=lambda i: abs(parts[i].start_s - curve["start_s"]), default=None)
        nan = float("nan")
        part = parts[index] if index is not None else None
        found = (part.start_s, part.end_s, part.radius_m) if part is not None else (nan, nan, nan)
        passed = (
            part is not None
            and abs(part.start_s - curve["start_s"]) <= tolerance_m
            and abs(part.end_s - curve["end_s"]) <= tolerance_m
            and abs(part.radius_m / curve["radius_m"] - 1.0) <= radius_tolerance
        )
        if passed:
            matched.add(index)
        checks.append(
            CurveCheck(
                truth["name"], curve["name"], curve["start_s"], curve["end_s"], curve["radius_m"], *found, passed=passed
            )
        )
    for i, part in enumerate(parts):
        if i not in matched:
            checks.append(
                CurveCheck(
                    truth["name"],
                    "extra",
                    float("nan"),
                    float("nan"),
                    float("nan"),
                    part.start_s,
                    part.end_s,
                    part.radius_m,
                    passed=False,
                )
            )
    return checks


def verify_networks(directory: Path, tolerance_m: float = 1.0, radius_tolerance: float = 0.01) -> VerificationReport:
    """Verify every network listed in ``directory/index.json``.

    Raises
    ------
    FileNotFoundError
        When the folder has no ``index.json`` (it is not a networks folder).
    """
    directory = Path(directory)
    index_file = directory / "index.json"
    if not index_file.is_file():
        raise FileNotFoundError(f"{directory} has no index.json: not a folder of csws test tracks")
    checks: list[CurveCheck] = []
    for entry in json.loads(index_file.read_text(encoding="utf-8"))["networks"]:
        truth = json.loads((directory / entry["truth_file"]).read_text(encoding="utf-8"))
        checks += verify_network(directory / entry["net_file"], truth, tolerance_m, radius_tolerance)
    return VerificationReport(tuple(checks), tolerance_m, radius_tolerance)
