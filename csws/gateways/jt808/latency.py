"""Where a report's time goes inside a gateway: seconds per stage, summarised as percentiles.

A gateway adds one sample per report to each stage it went through (read to queued, waiting for
the work thread, the evaluation of its group, the hand-back to the event loop, the text written),
and prints them when it stops as one line, ``stages (p50/p99 ms): wait 1.2/40.1, ...``, which
:func:`parse_stages` reads back (the benchmark does).
"""

from __future__ import annotations

import re
from collections import deque

import numpy as np

__all__ = ["STAGES_PREFIX", "StageTimes", "parse_stages"]

#: How the line of stage times starts.
STAGES_PREFIX = "stages (p50/p99 ms):"
_STAGE = re.compile(r"([\w:]+) ([\d.]+|nan)/([\d.]+|nan)")


class StageTimes:
    """Seconds spent in each named stage, the newest ``keep`` samples of each.

    Parameters
    ----------
    keep
        Samples kept per stage (older ones are forgotten, so memory stays bounded on a long run).
    """

    def __init__(self, keep: int = 200_000) -> None:
        self.keep = keep
        self._samples: dict[str, deque[float]] = {}

    def add(self, stage: str, seconds: float, count: int = 1) -> None:
        """Count ``seconds`` in ``stage`` ``count`` times (once per report of a group)."""
        samples = self._samples.get(stage)
        if samples is None:
            samples = self._samples[stage] = deque(maxlen=self.keep)
        if count == 1:
            samples.append(seconds)
        else:
            samples.extend([seconds] * count)

    def percentiles_ms(self, stage: str, quantiles: tuple[float, ...] = (50.0, 99.0)) -> tuple[float, ...]:
        """The ``quantiles`` (in percent) of ``stage``, ms; NaN for a stage without samples."""
        samples = self._samples.get(stage)
        if not samples:
            return tuple(float("nan") for _ in quantiles)
        values = np.percentile(np.fromiter(samples, float, len(samples)) * 1000.0, quantiles)
        return tuple(float(value) for value in values)

    def line(self) -> str:
        """All stages, in the order first seen, as ``stages (p50/p99 ms): name p50/p99, ...``."""
        parts = []
        for stage in self._samples:
            p50, p99 = self.percentiles_ms(stage)
            parts.append(f"{stage} {p50:.1f}/{p99:.1f}")
        return f"{STAGES_PREFIX} {', '.join(parts)}"


def parse_stages(text: str) -> dict[str, tuple[float, float]]:
    """The p50 and p99 (ms) of each stage of the :meth:`StageTimes.line` in ``text`` (empty without one)."""
    start = text.find(STAGES_PREFIX)
    if start < 0:
        return {}
    line = text[start + len(STAGES_PREFIX) :].split("\n", 1)[0]
    return {name: (float(p50), float(p99)) for name, p50, p99 in _STAGE.findall(line)}
