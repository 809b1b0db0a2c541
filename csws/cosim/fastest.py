"""The farthest and fastest a vehicle SUMO drives can go, step by step, and the first step at which a condition on
that drive holds: the curve warning's schedule (:mod:`csws.cosim.schedule`) sleeps a vehicle until then."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["MOST_STEPS", "FastestDrive", "first_step"]


class FastestDrive:
    """The farthest vehicles can go: from ``speed_mps`` each one's speed rises by at most ``accel_mps2`` per second
    (SUMO's car-following models never accelerate faster) up to ``bound_mps``, and each step it advances that step's
    speed times the step (SUMO's default Euler update; the ballistic one advances less). Arrays, one per vehicle."""

    def __init__(self, speed_mps: np.ndarray, bound_mps: np.ndarray, accel_mps2: np.ndarray, step_s: float) -> None:
        self.speed0_mps, self.bound_mps, self.step_s = speed_mps, bound_mps, step_s
        gain_mps = accel_mps2 * step_s
        rises = (0.0 < gain_mps) & (gain_mps < math.inf)
        #: The speed gained per step where it rises (0 where the gain is 0 or infinite: at its bound at once).
        self.gain_mps = np.where(rises, gain_mps, 0.0)
        #: Steps at which the speed still rises below the bound.
        self.rising = np.where(rises, np.floor((bound_mps - speed_mps) / np.where(rises, gain_mps, 1.0)), 0.0)

    def speed_mps(self, which: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """The highest speed of the vehicles ``which`` after ``steps`` steps, m/s."""
        rising_mps = self.speed0_mps[which] + self.gain_mps[which] * steps
        return np.where(steps > self.rising[which], self.bound_mps[which], rising_mps)

    def first_step_at(self, speed_mps: np.ndarray) -> np.ndarray:
        """Per vehicle, the first step from 1 on at which its highest speed could be ``speed_mps``; inf where its
        bound is below it."""
        with np.errstate(divide="ignore", invalid="ignore"):
            rising = np.ceil((speed_mps - self.speed0_mps) / self.gain_mps)
        steps = np.where(self.gain_mps > 0.0, np.minimum(rising, self.rising + 1.0), 1.0)
        steps = np.where(self.speed0_mps >= speed_mps, 1.0, np.maximum(steps, 1.0))
        return np.where(self.bound_mps >= speed_mps, steps, math.inf)

    def lane_m(self, which: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """The longest lane distance the vehicles ``which`` drive in ``steps`` steps, m."""
        rising = np.minimum(steps, self.rising[which])
        rising_m = np.where(rising > 0, self._rising_m(which, rising), 0.0)
        return self.step_s * (rising_m + (steps - rising) * self.bound_mps[which])

    def _rising_m(self, which: np.ndarray, rising: np.ndarray) -> np.ndarray:
        """The lane distance over the first ``rising`` steps while the speed rises, in steps (m over the step)."""
        return rising * self.speed0_mps[which] + self.gain_mps[which] * rising * (rising + 1) / 2

    def first_step_guess(
        self, target_m: np.ndarray, factor: np.ndarray, reach_m: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """Per vehicle, the first step at which the lane distance driven plus ``factor`` times the reach at the speed
        then, ``reach_m(speed_mps)``, could be ``target_m``, as the closed form gives it: a quadratic in the steps
        while the speed still rises (the reach, formula (1) plus the allowance, is a quadratic in the speed: its
        coefficients are read from it at 1 and 2 m/s), linear once at the bound. A first guess: rounding may put it
        a step off."""
        every = np.arange(self.rising.size)
        rising_m = np.where(self.rising > 0, self._rising_m(every, self.rising), 0.0)
        reach_at_bound_m = reach_m(self.bound_mps)
        at_bound = self.rising + np.ceil(
            ((target_m - factor * reach_at_bound_m) / self.step_s - rising_m) / self.bound_mps
        )
        at_one_m, at_two_m = reach_m(np.ones(every.size)), reach_m(np.full(every.size, 2.0))
        square, linear = (at_two_m - 2.0 * at_one_m) / 2.0, at_one_m - (at_two_m - 2.0 * at_one_m) / 2.0
        speed_mps, gain_mps = self.speed0_mps, self.gain_mps
        a = self.step_s * gain_mps / 2.0 + factor * square * gain_mps**2
        b = self.step_s * (speed_mps + gain_mps / 2.0) + factor * gain_mps * (linear + 2.0 * square * speed_mps)
        c = factor * (linear * speed_mps + square * speed_mps**2) - target_m
        with np.errstate(divide="ignore", invalid="ignore"):  # no curve part ahead: an infinite target
            root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
            while_rising = np.ceil(np.where(a > 0.0, (root - b) / (2.0 * a), np.inf))
        guess = np.where(while_rising <= self.rising, while_rising, np.maximum(at_bound, self.rising + 1.0))
        return np.nan_to_num(guess, nan=1.0, posinf=float(MOST_STEPS), neginf=1.0)


#: The most steps a vehicle sleeps.
MOST_STEPS = 1 << 24


def first_step(
    holds: Callable[[np.ndarray, np.ndarray], np.ndarray], guess: np.ndarray, most: int = MOST_STEPS
) -> np.ndarray:
    """Per vehicle, the first step from 1 on at which ``holds(vehicles, steps)`` (false until then, true from then
    on), ``most`` where it holds at none up to it: ``guess`` where it holds there and not the step before, else
    found by doubling then halving."""
    count = guess.size
    guess = np.clip(guess, 1, most).astype(np.int64)
    which = np.arange(count)
    right = (holds(which, guess) | (guess == most)) & ((guess == 1) | ~holds(which, guess - 1))
    first = np.where(right, guess, most)
    which = which[~right]
    ones = np.ones(which.size, dtype=np.int64)
    at_once = holds(which, ones)
    first[which[at_once]] = 1
    which, low, high = which[~at_once], ones[~at_once], 2 * ones[~at_once]
    found, found_low, found_high = [], [], []
    while which.size:  # doubling: [low, high) brackets the first step where it holds at high
        held = holds(which, high)
        found.append(which[held])
        found_low.append(low[held])
        found_high.append(high[held])
        going = ~held & (high < most)
        which, low, high = which[going], high[going], 2 * high[going]
    which, low, high = (np.concatenate([np.zeros(0, dtype=np.int64), *part]) for part in (found, found_low, found_high))
    while which.size:  # halving
        wide = high - low > 1
        first[which[~wide]] = high[~wide]
        which, low, high = which[wide], low[wide], high[wide]
        if not which.size:
            break
        middle = (low + high) // 2
        held = holds(which, middle)
        low, high = np.where(held, low, middle), np.where(held, middle, high)
    return first
