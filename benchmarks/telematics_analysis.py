"""The telematics benchmark's pure parts: sampling a trajectory with GNSS noise, and judging a feed's
warning onsets against the reference's.

* :func:`sample_mask` picks a feed's fix instants from the recorded steps, :func:`noisy_fixes` adds
  position, heading and speed noise and drops fixes, each from its own seeded generator.
* :func:`onsets` finds a vehicle's warning onsets (level 0 -> 1 or 2) in its answers;
  :func:`match_onsets` pairs the feed's onsets with the reference's within a window;
  :func:`repeat_onsets` counts onsets that follow the vehicle's previous warning within a gap
  (a warning switched off and on again: flicker).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Noise", "Fixes", "sample_mask", "noisy_fixes", "onsets", "match_onsets", "OnsetMatch", "repeat_onsets"]


@dataclass(frozen=True)
class Noise:
    """A GNSS receiver's errors.

    Attributes
    ----------
    position_sigma_m
        Standard deviation of the position error along each of east and north, m.
    heading_sigma_deg
        Standard deviation of the heading error, degrees.
    speed_sigma_kmh
        Standard deviation of the speed error, km/h.
    drop_share
        Share of fixes lost on the way (each independently).
    """

    position_sigma_m: float
    heading_sigma_deg: float
    speed_sigma_kmh: float
    drop_share: float


@dataclass(frozen=True)
class Fixes:
    """Fixes as sent: which rows of the trajectory survived and their measured values."""

    kept: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    heading_deg: np.ndarray
    speed_kmh: np.ndarray


def sample_mask(step: np.ndarray, vehicle: np.ndarray, interval_steps: int, batch_steps: int) -> np.ndarray:
    """Which rows are fixes: each vehicle reports every ``interval_steps`` steps, on steps that are whole
    batches (multiples of ``batch_steps``), its phase among the batches set by its index so that the
    fleet's reports spread evenly over the batches.

    Parameters
    ----------
    step, vehicle
        Each row's step and vehicle index.
    interval_steps
        Steps between one vehicle's fixes (a multiple of ``batch_steps``).
    batch_steps
        Steps between batches.
    """
    if interval_steps % batch_steps:
        raise ValueError(f"a fix interval of {interval_steps} steps is not a whole number of batches")
    phases = interval_steps // batch_steps
    phase_steps = (vehicle % phases) * batch_steps
    return (step % batch_steps == 0) & ((step - phase_steps) % interval_steps == 0)


def noisy_fixes(
    x_m: np.ndarray,
    y_m: np.ndarray,
    heading_deg: np.ndarray,
    speed_kmh: np.ndarray,
    noise: Noise,
    rng: np.random.Generator,
) -> Fixes:
    """The measured fixes of true positions, headings and speeds: independent Gaussian errors with the
    noise's standard deviations (heading wrapped into [0, 360), speed kept at 0 or more), and each fix
    dropped with the noise's share."""
    count = len(x_m)
    error_m = rng.normal(0.0, noise.position_sigma_m, size=(2, count))
    heading_error_deg = rng.normal(0.0, noise.heading_sigma_deg, size=count)
    speed_error_kmh = rng.normal(0.0, noise.speed_sigma_kmh, size=count)
    kept = rng.random(count) >= noise.drop_share
    return Fixes(
        kept=kept,
        x_m=(x_m + error_m[0])[kept],
        y_m=(y_m + error_m[1])[kept],
        heading_deg=_wrapped_deg(heading_deg + heading_error_deg)[kept],
        speed_kmh=np.maximum(speed_kmh + speed_error_kmh, 0.0)[kept],
    )


def _wrapped_deg(angle_deg: np.ndarray) -> np.ndarray:
    """Angles wrapped into [0, 360), degrees (``np.mod`` alone gives 360 for a tiny negative angle)."""
    wrapped = np.mod(angle_deg, 360.0)
    return np.where(wrapped >= 360.0, 0.0, wrapped)


def onsets(levels: np.ndarray) -> np.ndarray:
    """Indices of the warning onsets in one vehicle's answers in time order: level 1 or 2 after 0 (or first)."""
    on = np.asarray(levels) > 0
    before = np.concatenate(([False], on[:-1]))
    return np.flatnonzero(on & ~before)


@dataclass(frozen=True)
class OnsetMatch:
    """The pairing of a feed's onsets with the reference's for one vehicle.

    Attributes
    ----------
    pairs
        (reference index, feed index) of each matched pair.
    unmatched_reference, unmatched_feed
        Indices of the onsets left without a partner.
    """

    pairs: list[tuple[int, int]]
    unmatched_reference: list[int]
    unmatched_feed: list[int]


def match_onsets(reference_s: np.ndarray, feed_s: np.ndarray, before_s: float, after_s: float) -> OnsetMatch:
    """Pair each reference onset, in time order, with the feed's earliest unpaired onset from ``before_s``
    before it to ``after_s`` after it.

    Parameters
    ----------
    reference_s, feed_s
        Onset times of one vehicle, s, ascending.
    before_s, after_s
        How early and how late a feed onset may be and still be the same warning, s.
    """
    used = np.zeros(len(feed_s), dtype=bool)
    pairs, unmatched_reference = [], []
    for r, time_s in enumerate(reference_s):
        candidates = np.flatnonzero(~used & (feed_s >= time_s - before_s) & (feed_s <= time_s + after_s))
        if len(candidates):
            used[candidates[0]] = True
            pairs.append((r, int(candidates[0])))
        else:
            unmatched_reference.append(r)
    return OnsetMatch(pairs, unmatched_reference, [int(f) for f in np.flatnonzero(~used)])


def repeat_onsets(times_s: np.ndarray, levels: np.ndarray, gap_s: float) -> int:
    """How many onsets of one vehicle come at most ``gap_s`` after its previous answer with a warning on:
    the warning switched off and on again."""
    levels = np.asarray(levels)
    starts = onsets(levels)
    on_times_s = np.asarray(times_s)[levels > 0]
    count = 0
    for index in starts:
        earlier = on_times_s[on_times_s < times_s[index]]
        count += bool(len(earlier)) and bool(times_s[index] - earlier[-1] <= gap_s)
    return count


def on_at(times_s: np.ndarray, levels: np.ndarray, start_s: float, end_s: float) -> bool:
    """Whether one vehicle's warning was on at an answer between ``start_s`` and ``end_s`` (inclusive)."""
    inside = (times_s >= start_s) & (times_s <= end_s)
    return bool(np.any(np.asarray(levels)[inside] > 0))
