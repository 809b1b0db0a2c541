"""Progress of long runs on stderr, for people at a terminal and for logs alike.

On a terminal it is a bar (tqdm). Anywhere else (CI, a pipe, a log file) it is one line
each time the run has gone another :data:`STEP_PERCENT` of the way, or, when the total
is not known, one line every :data:`QUIET_S` seconds::

    csws conformance: 37 of 185 tasks (20 %)
    csws cosim: 120.0 sim s
    csws sweep: 6 of 12 runs (50 %), about 1 min 10 s left

Amounts are printed with the given number of decimals, so a sum of float steps prints
as 377.2, not 377.20000000001727.
"""

from __future__ import annotations

import math
import sys
import time
from typing import TextIO

__all__ = ["Progress", "STEP_PERCENT", "QUIET_S"]

#: Lines are printed each time this much more of the total is done, percent.
STEP_PERCENT = 10.0
#: Without a total, a line is printed when this long has passed since the last one, s.
QUIET_S = 30.0


class Progress:
    """How far a run is, shown on ``stream`` (stderr).

    Parameters
    ----------
    command
        What runs, as the line's prefix: ``"conformance"`` prints ``csws conformance: ...``.
    total
        The amount at the end, None when not known.
    unit
        What is counted (``"tasks"``, ``"sim s"``).
    decimals
        Decimals the amounts are shown with.
    enabled
        False shows nothing (a library call).
    done
        The amount done before this run started (a resumed sweep's runs already done).
    time_left
        Also show an estimate of the time left, from the pace so far (needs ``total``).
    """

    def __init__(
        self,
        command: str,
        total: float | None,
        unit: str,
        decimals: int = 0,
        enabled: bool = True,
        stream: TextIO | None = None,
        *,
        done: float = 0.0,
        time_left: bool = False,
    ) -> None:
        self.command, self.total, self.unit, self.decimals = command, total, unit, decimals
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.done = self._done_before = done
        self._time_left = time_left and total is not None
        self._bar = None
        self._next_percent = (
            (math.floor(100.0 * done / total / STEP_PERCENT) + 1) * STEP_PERCENT if total else STEP_PERCENT
        )
        self._started_s = self._last_line_s = time.monotonic()
        if enabled and self.stream.isatty():
            from tqdm import tqdm

            amount = f"{{n:.{decimals}f}}" + ("" if total is None else f"/{{total:.{decimals}f}}")
            self._bar = tqdm(
                total=total,
                initial=done,
                unit=unit,
                file=self.stream,
                desc=f"csws {command}",
                bar_format="{desc}: "
                + ("{percentage:3.0f}%|{bar}| " if total else "")
                + amount
                + f" {unit} [{{elapsed}}"
                + ("<{remaining}" if self._time_left else "")
                + "]",
            )

    def update(self, amount: float = 1.0) -> None:
        """The run has done ``amount`` more."""
        self.done += amount
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(amount)
        elif self.total:
            percent = 100.0 * self.done / self.total
            if percent + 1e-9 >= self._next_percent:
                self._line(
                    f"{self._amount(self.done)} of {self._amount(self.total)} {self.unit} "
                    f"({math.floor(percent + 1e-9):.0f} %){self._left()}"
                )
                self._next_percent = (math.floor((percent + 1e-9) / STEP_PERCENT) + 1) * STEP_PERCENT
        elif time.monotonic() - self._last_line_s >= QUIET_S:
            self._line(f"{self._amount(self.done)} {self.unit}")

    def close(self) -> None:
        """The run is over (or was stopped)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def _left(self) -> str:
        """``, about 1 min 10 s left`` from the pace since the start; empty when not asked for or not known."""
        done_here = self.done - self._done_before
        if not self._time_left or self.total is None or done_here <= 0 or self.done >= self.total:
            return ""
        left_s = round((time.monotonic() - self._started_s) * (self.total - self.done) / done_here)
        minutes, seconds = divmod(left_s, 60)
        return f", about {f'{minutes} min ' if minutes else ''}{seconds} s left"

    def _amount(self, value: float) -> str:
        return f"{value:.{self.decimals}f}"

    def _line(self, text: str) -> None:
        print(f"csws {self.command}: {text}", file=self.stream, flush=True)
        self._last_line_s = time.monotonic()
