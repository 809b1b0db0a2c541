"""An optional model of the driver's response to a warning: react, brake, hold.

Formula (1) sizes the warning distance for a driver who reacts in 0.8 s and then brakes
at g/2 = 4.9 m/s^2 to the warning speed. This model is that driver:

* a warning comes on (level 0 -> 1 or 2): the driver reacts after ``reaction_s``, keeping
  the speed meanwhile (as formula (1) assumes);
* then, while warned, the driver brakes at ``decel_mps2`` toward just below the target's
  warning speed (the lowest seen since the warning came on: a lower target takes over);
* the driver keeps that speed until the warning is off and the vehicle is ``hold_m``
  past the target CPOI (the start of the curve part), then hands the vehicle back to SUMO.

Not every vehicle need respond: ``equipped_share`` of the fleet carries the system (the
others never see a warning) and ``compliance_share`` of the equipped drivers heed it. Who is
equipped and who complies is drawn per vehicle from a hash of its id and ``draw_seed``
(:func:`vehicle_draw`), so the same vehicle is drawn alike in every run of that seed,
whatever the order vehicles appear in.

With the forward collision warning on, the same driver answers its warnings too
(:meth:`DriverResponse.fcw_command`): as a level-2 curve warning, braking toward the speed of
the vehicle ahead; where both warnings ask for a speed, the lower one is commanded.

It sees only what an on-board unit shows (level, target warning speed and distance), so
it works the same whether the answers come from the library or the service. With it, no
vehicle enters a curve above its level-1 warning speed: the warning distance includes the
reaction and braking distance, plus the latency allowance.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

from csws.standard import G_MPS2, REACTION_TIME_S, kmh_to_mps

__all__ = ["DriverSettings", "DriverResponse", "vehicle_draw", "is_equipped"]


@dataclass(frozen=True)
class DriverSettings:
    """The modelled driver.

    Attributes
    ----------
    reaction_s
        Time from the warning to braking, s (formula (1): 0.8 s).
    decel_mps2
        Braking deceleration, m/s^2 (formula (1): g/2).
    hold_m
        The driver holds the reduced speed this far past the target CPOI, m: longer than
        the longest curve of the bundled networks (177 m, Table 7), so that no one speeds
        up inside a curve.
    below_kmh
        The driver aims this far below the target's warning speed, km/h: a level that is on
        stays on down to the release rule's margin of 1 km/h below V_w (:mod:`csws.warning.release`),
        below that the next target (level 1 after level 2) takes over once the rule's hold
        has passed.
    equipped_share
        Share of the vehicles that carry the system, 0-1; the others go on as SUMO drives them.
    compliance_share
        Share of the equipped vehicles' drivers that respond to a warning, 0-1.
    draw_seed
        Seed of the per-vehicle draws of equipment and compliance.
    """

    reaction_s: float = REACTION_TIME_S
    decel_mps2: float = G_MPS2 / 2
    hold_m: float = 200.0
    below_kmh: float = 1.5
    equipped_share: float = 1.0
    compliance_share: float = 1.0
    draw_seed: int = 0

    def responds(self, vehicle_id: str) -> bool:
        """Whether the vehicle is equipped and its driver complies."""
        return is_equipped(vehicle_id, self.equipped_share, self.draw_seed) and (
            self.compliance_share >= 1.0 or vehicle_draw(vehicle_id, self.draw_seed, "complies") < self.compliance_share
        )


def vehicle_draw(vehicle_id: str, seed: int, what: str) -> float:
    """A number in [0, 1) drawn for one vehicle from its id, ``seed`` and what is drawn (independent
    draws for different ``what``): the same in every run and process."""
    digest = hashlib.blake2b(f"{seed}:{what}:{vehicle_id}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big") / 2.0**64


def is_equipped(vehicle_id: str, equipped_share: float, seed: int) -> bool:
    """Whether the vehicle carries the system, in a fleet where ``equipped_share`` of the vehicles do."""
    return equipped_share >= 1.0 or vehicle_draw(vehicle_id, seed, "equipped") < equipped_share


@dataclass
class _Driver:
    """One driver's state."""

    warned_since_s: float | None = None
    onset_speed_mps: float = 0.0
    goal_mps: float | None = None
    release_odometer_m: float = 0.0


@dataclass
class _FcwDriver:
    """One driver's answer to a forward collision warning: since when warned, and the speed it brakes to."""

    warned_since_s: float
    goal_mps: float | None = None


@dataclass
class DriverResponse:
    """The drivers of a fleet; :meth:`commands` gives the speed commands of one step."""

    settings: DriverSettings = field(default_factory=DriverSettings)
    drivers: dict[str, _Driver] = field(default_factory=dict)
    fcw_drivers: dict[str, _FcwDriver] = field(default_factory=dict)

    def commands(
        self,
        time_s: float,
        step_s: float,
        vehicle_id: str,
        level: int,
        target_speed_kmh: float | None,
        target_distance_m: float | None,
        speed_mps: float,
        odometer_m: float,
    ) -> float | None:
        """The speed to command this step (m/s), -1 to hand the vehicle back to SUMO, None to leave it alone.

        During the reaction time the vehicle keeps the speed it had when the warning came
        on (formula (1) assumes V for those 0.8 s); then it brakes and holds.
        """
        driver = self.drivers.get(vehicle_id)
        if driver is None:
            if level == 0 or not self.settings.responds(vehicle_id):
                return None
            driver = self.drivers[vehicle_id] = _Driver(warned_since_s=time_s, onset_speed_mps=speed_mps)
        if level > 0:
            if target_speed_kmh is None or target_distance_m is None:
                raise ValueError(f"vehicle {vehicle_id!r} is warned without a target CPOI")
            warned_since_s = driver.warned_since_s
            if warned_since_s is None:
                warned_since_s = driver.warned_since_s = time_s
                driver.onset_speed_mps = speed_mps
            if time_s - warned_since_s >= self.settings.reaction_s - 1e-9:
                self._aim(driver, target_speed_kmh, odometer_m + target_distance_m)
            elif driver.goal_mps is None:
                return driver.onset_speed_mps
        else:
            driver.warned_since_s = None
        goal_mps = driver.goal_mps
        if goal_mps is None or (level == 0 and odometer_m >= driver.release_odometer_m):
            del self.drivers[vehicle_id]
            return -1.0
        return max(goal_mps, speed_mps - self.settings.decel_mps2 * step_s)

    def _aim(self, driver: _Driver, target_speed_kmh: float, target_odometer_m: float) -> None:
        """After the reaction time: brake toward just below the lowest warning speed seen since the
        warning came on, and hold it until ``hold_m`` past the target CPOI (at ``target_odometer_m``)."""
        goal_mps = kmh_to_mps(target_speed_kmh - self.settings.below_kmh)
        driver.goal_mps = goal_mps if driver.goal_mps is None else min(driver.goal_mps, goal_mps)
        driver.release_odometer_m = max(driver.release_odometer_m, target_odometer_m + self.settings.hold_m)

    def fcw_command(
        self, time_s: float, step_s: float, vehicle_id: str, level: int, range_rate_mps: float | None, speed_mps: float
    ) -> float | None:
        """The answer to a forward collision warning (``csws cosim --systems csws,fcw``): the speed to
        command this step (m/s), -1 to hand the vehicle back to SUMO, None to leave it alone.

        The driver answers a warning of either FCW level as a level-2 curve warning: after
        ``reaction_s`` (SUMO's driver keeps driving meanwhile) it brakes at ``decel_mps2`` toward
        ``below_kmh`` under the target's speed (v_SV + v_r, at least 0; the last one seen while the
        system sees no target, e.g. below V_min), and hands the vehicle back once the warning is
        off and it no longer closes on the target or has come down to that speed.
        """
        driver = self.fcw_drivers.get(vehicle_id)
        if driver is None:
            if level == 0 or not self.settings.responds(vehicle_id):
                return None
            driver = self.fcw_drivers[vehicle_id] = _FcwDriver(time_s)
        reacted = time_s - driver.warned_since_s >= self.settings.reaction_s - 1e-9
        if reacted and range_rate_mps is not None:
            driver.goal_mps = max(0.0, speed_mps + range_rate_mps - kmh_to_mps(self.settings.below_kmh))
        if level == 0 and (
            driver.goal_mps is None
            or speed_mps <= driver.goal_mps
            or (range_rate_mps is not None and range_rate_mps >= 0.0)
        ):
            del self.fcw_drivers[vehicle_id]
            return -1.0
        if driver.goal_mps is None:
            return None
        return max(driver.goal_mps, speed_mps - self.settings.decel_mps2 * step_s)

    def forget(self, vehicle_id: str) -> None:
        """Drop a vehicle that left."""
        self.drivers.pop(vehicle_id, None)
        self.fcw_drivers.pop(vehicle_id, None)
