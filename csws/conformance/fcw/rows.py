"""The rows of the forward collision warning suite: GB/T 33577-2017 5.4-5.5 and IVISTA's FCW scenarios.

Each row is one test for a truck or bus subject vehicle (``sv``): the vehicles at the start,
what they do (:attr:`FcwRow.script`), and the criterion the judge applies
(:mod:`csws.conformance.fcw.judge`):

============  ===========================================================================
script        what happens
============  ===========================================================================
approach      every vehicle at its constant speed; the test ends at the warning
lead_brakes   after ``STABLE_S`` the target brakes at 0.3 g (5.5.2.1.2)
two_leads     5.5.2.2: the subject closes on two leads until warned, falls back behind
              the nearer one, then the nearer one brakes until the subject is warned again
adjacent      5.5.3: the adjacent-lane vehicle brakes to well below the others' speed and
              is passed without a warning; then the target brakes until the warning
============  ===========================================================================

Where GB/T 33577 and the Russian text of ISO 15623 differ, GB/T is followed (docs/fcw.md):
the subject is less than 0.5 m off the target's axis in 5.5.3.1 (both drive in the lane
centre), and the curve test of 5.5.3.2 ends at the collision warning, not the preliminary one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from csws.fcw.physics import formula_5_clearance_m, warning_clearance_m
from csws.fcw.settings import STANDARD_GRAVITY_MPS2, FcwSettings
from csws.fcw.target import CurveClass, curve_start_speed_mps
from csws.networks.fcw_tracks import CURVE_RADII_M
from csws.standard import kmh_to_mps

__all__ = [
    "STABLE_S",
    "LEAD_BRAKE_MPS2",
    "REFERENCE_CLEARANCE_M",
    "CAR_LENGTH_M",
    "Actor",
    "FcwRow",
    "fcw_rows",
    "approach_row",
    "curve_row",
    "straight_adjacent_row",
]

#: Every vehicle holds its speed this long before anything happens, s (a stable start).
STABLE_S = 3.0
#: The braking of the leads (5.5.2.1.2) and of the adjacent-lane vehicle, m/s^2: 0.3 g.
LEAD_BRAKE_MPS2 = 0.3 * STANDARD_GRAVITY_MPS2
#: Where the approach tests begin: the clearance of 5.5.2.1.1, 5.5.2.1.3 and IVISTA A.1, m.
START_CLEARANCE_M = 150.0
#: 5.4.2: the reference clearance d at t0, m.
REFERENCE_CLEARANCE_M = 100.0
#: Where the rows come from.
GB, IVISTA = "GB/T 33577-2017", "IVISTA-SM-ISI.SA.AEB-TP-A0-2023"
#: Length of the passenger-car targets, m (the vType ``car``).
CAR_LENGTH_M = 4.5


@dataclass(frozen=True)
class Actor:
    """A vehicle of a row at the start.

    Attributes
    ----------
    vehicle_id
        ``sv`` (the subject), ``tv`` (the target), ``tv2`` (the farther lead), ``adj`` (the adjacent-lane vehicle).
    vtype
        ``truck`` (the subject), ``car`` (a passenger-car target), ``truck_target`` (IVISTA's truck target).
    lane
        Lane index (0 the right lane; on the curve tracks the outer one).
    ahead_m
        Clearance from the subject's front to this vehicle's rear at the start, m (0 for the subject).
    speed_mps
        Its speed at the start, m/s.
    """

    vehicle_id: str
    vtype: str
    lane: int
    ahead_m: float
    speed_mps: float


@dataclass(frozen=True)
class FcwRow:
    """One test.

    Attributes
    ----------
    row_id
        E.g. ``"GB-5.5.2.1.2"``, ``"IVISTA-A.1.1-truck"``, ``"GB-5.5.3.2-III"``.
    source, clause, title
        Where it comes from and what it is.
    track
        The FCW track it runs on (``networks/fcw``).
    actors
        The vehicles, the subject first.
    script
        What happens (see the module's table).
    level
        The warning the test waits for: 2 the collision warning, 1 the preliminary one.
    least_ttc_s
        The TTC the warning must come at or before, s; None where another criterion applies.
    speed_tolerance_mps
        The subject's (and constant-speed target's) speed stays this close to its test speed, m/s.
    least_clearance_m
        5.4.1: the clearance at the warning is at least this (formula (5)); else None.
    set_distance_m
        5.4.2: the system's set warning distance the measured one is compared with; else None.
    avoidance
        The physical criterion of the Euro NCAP rows (:mod:`csws.conformance.fcw.avoidance`): a driver
        reacting 0.8 s after the warning and braking at 0.68 g avoids contact.
    warning_required
        False for a subject below V_min (4.3.3: the system is in standby): any outcome passes.
    lead_brake_mps2
        The target's deceleration when it brakes, m/s^2 (0.3 g in GB/T 33577 and NHTSA).
    repetitions
        Runs per step length the row's own protocol asks (NHTSA: 7); None for the suite's number.
    least_passing_runs
        A group passes when at least this many of its runs do (NHTSA: 5 of 7); None for all of them.
    known_issue
        Why the shipped system is known to fail the row, shown with its failed runs; empty for none.
    """

    row_id: str
    source: str
    clause: str
    title: str
    track: str
    actors: tuple[Actor, ...]
    script: str
    level: int = 2
    least_ttc_s: float | None = None
    speed_tolerance_mps: float = 1.0
    least_clearance_m: float | None = None
    set_distance_m: float | None = None
    avoidance: bool = False
    warning_required: bool = True
    lead_brake_mps2: float = LEAD_BRAKE_MPS2
    repetitions: int | None = None
    least_passing_runs: int | None = None
    known_issue: str = ""

    def actor(self, vehicle_id: str) -> Actor:
        """The actor of that id (KeyError for a vehicle the row does not have)."""
        for actor in self.actors:
            if actor.vehicle_id == vehicle_id:
                return actor
        raise KeyError(f"row {self.row_id} has no vehicle {vehicle_id!r}")


def approach_row(
    row_id: str,
    source: str,
    clause: str,
    title: str,
    subject_mps: float,
    lead_mps: float,
    lead_type: str = "car",
    start_clearance_m: float = START_CLEARANCE_M,
    **criteria: Any,
) -> FcwRow:
    """A subject closing at constant speed on a lead at constant speed, from ``start_clearance_m`` plus the
    stable time."""
    start_m = start_clearance_m + STABLE_S * (subject_mps - lead_mps)
    return FcwRow(
        row_id,
        source,
        clause,
        title,
        "fcw_straight",
        (Actor("sv", "truck", 0, 0.0, subject_mps), Actor("tv", lead_type, 0, start_m, lead_mps)),
        "approach",
        **criteria,
    )


def curve_row(curve_class: CurveClass, radius_m: float, settings: FcwSettings, lateral_share: float = 1.0) -> FcwRow:
    """5.5.3.2 on the class's curve at V_circle_start of formula (6), with ``lateral_share`` of the class's
    a_lateral_max (1 the standard's speed; a lower share a lower lateral acceleration the formula allows)."""
    # sqrt((share a_lateral_max) R) = sqrt(a_lateral_max (share R)): formula (6) with the share on R
    speed_mps = curve_start_speed_mps(curve_class, radius_m * lateral_share, settings.max_speed_mps)
    standard = lateral_share == 1.0
    actors = (
        Actor("sv", "truck", 1, 0.0, speed_mps),
        Actor("adj", "car", 0, 15.0, speed_mps),
        Actor("tv", "car", 1, 2.0 * speed_mps, speed_mps),
    )
    return FcwRow(
        f"GB-5.5.3.2-{curve_class.name}" + ("" if standard else f"-{lateral_share:g}a"),
        GB,
        "5.5.3.2",
        f"curve R {radius_m:g} m (class {curve_class.name}), adjacent vehicle in the outer lane, {speed_mps:.1f} m/s"
        + ("" if standard else f" ({lateral_share:g} a_lateral_max)"),
        f"fcw_curve_r{radius_m:g}",
        actors,
        "adjacent",
    )


def fcw_rows(settings: FcwSettings = FcwSettings()) -> list[FcwRow]:
    """Every row: GB/T 33577 5.4-5.5 that applies to a truck or bus, IVISTA A.1, then the added tracks
    (:mod:`csws.conformance.fcw.more_rows`: NHTSA, Euro NCAP CCR, 5.5.3 at other speeds)."""
    from .more_rows import more_fcw_rows  # it builds on this module's helpers

    return [
        *_warning_distance_rows(settings),
        *_lead_rows(),
        *_adjacent_rows(settings),
        *_ivista_rows(),
        *more_fcw_rows(settings),
    ]


def _warning_distance_rows(settings: FcwSettings) -> list[FcwRow]:
    """GB/T 33577 5.4: the warning distance's range (formula (5)) and its accuracy (4.7.2)."""
    return [
        approach_row(
            "GB-5.4.1",
            GB,
            "5.4.1",
            "warning distance range: 20 m/s behind 8 m/s",
            20.0,
            8.0,
            speed_tolerance_mps=1.0,
            least_clearance_m=float(formula_5_clearance_m(12.0)),
        ),
        approach_row(
            "GB-5.4.2",
            GB,
            "5.4.2",
            "warning distance accuracy: 20 m/s toward a stationary target",
            20.0,
            0.0,
            set_distance_m=float(warning_clearance_m(20.0, 0.0, settings)),
        ),
    ]


def _lead_rows() -> list[FcwRow]:
    """GB/T 33577 5.5.2: a stationary, a braking and a slower lead, and two leads in line."""
    return [
        approach_row("GB-5.5.2.1.1", GB, "5.5.2.1.1", "stationary lead, 20 m/s", 20.0, 0.0, least_ttc_s=2.1),
        FcwRow(
            "GB-5.5.2.1.2",
            GB,
            "5.5.2.1.2",
            "lead braking at 0.3 g, both 20 m/s, 30 m apart",
            "fcw_straight",
            (Actor("sv", "truck", 0, 0.0, 20.0), Actor("tv", "car", 0, 30.0, 20.0)),
            "lead_brakes",
            least_ttc_s=2.4,
        ),
        approach_row("GB-5.5.2.1.3", GB, "5.5.2.1.3", "slower lead, 20 m/s behind 9 m/s", 20.0, 9.0, least_ttc_s=2.0),
        FcwRow(
            "GB-5.5.2.2",
            GB,
            "5.5.2.2",
            "two leads in line, 0.6 s apart: the warnings are for the nearer",
            "fcw_straight",
            (
                Actor("sv", "truck", 0, 0.0, 20.0),
                Actor("tv", "car", 0, 40.0, 20.0),
                Actor("tv2", "car", 0, 40.0 + CAR_LENGTH_M + 0.6 * 20.0, 20.0),
            ),
            "two_leads",
        ),
    ]


def _adjacent_rows(settings: FcwSettings) -> list[FcwRow]:
    """GB/T 33577 5.5.3: an adjacent-lane vehicle on the straight and on each class's curve."""
    curves = [
        curve_row(curve_class, radius_m, settings)
        for curve_class, radius_m in zip(CurveClass, CURVE_RADII_M, strict=False)
    ]
    return [straight_adjacent_row(20.0), *curves]


def straight_adjacent_row(speed_mps: float) -> FcwRow:
    """5.5.3.1 at ``speed_mps`` (the standard's 20 m/s, or another): the target 2 s ahead, the adjacent
    vehicle 15 m ahead in the next lane."""
    suffix = "" if speed_mps == 20.0 else f"-{speed_mps:g}mps"
    return FcwRow(
        f"GB-5.5.3.1{suffix}",
        GB,
        "5.5.3.1",
        f"straight road, adjacent vehicle 3.5 m to the side, {speed_mps:g} m/s",
        "fcw_straight",
        (
            Actor("sv", "truck", 1, 0.0, speed_mps),
            Actor("adj", "car", 0, 15.0, speed_mps),
            Actor("tv", "car", 1, 2.0 * speed_mps, speed_mps),
        ),
        "adjacent",
        level=1,
    )


def _ivista_rows() -> list[FcwRow]:
    """IVISTA A.1: stationary car and truck targets at 72 km/h, a target at 20 km/h at 80 km/h."""
    km = kmh_to_mps(1.0)
    rows = [
        approach_row(
            f"IVISTA-A.1.1-{kind}",
            IVISTA,
            "A.1.1",
            f"stationary {kind} target, 72 km/h",
            kmh_to_mps(72.0),
            0.0,
            lead_type=vtype,
            least_ttc_s=2.1,
            speed_tolerance_mps=km,
        )
        for kind, vtype in (("car", "car"), ("truck", "truck_target"))
    ]
    rows.append(
        approach_row(
            "IVISTA-A.1.2",
            IVISTA,
            "A.1.2",
            "target at 20 km/h, 80 km/h",
            kmh_to_mps(80.0),
            kmh_to_mps(20.0),
            least_ttc_s=2.0,
            speed_tolerance_mps=km,
        )
    )
    return rows
