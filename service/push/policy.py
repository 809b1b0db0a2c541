"""When a failed delivery is tried again, and when it is given up.

Exponential backoff with jitter: the n-th failure waits ``first_delay_s * 2**(n-1)`` (at most
``max_delay_s``) times a random factor in [0.5, 1), so that the deliveries of many events that failed
together do not come back together. An event is tried at most ``max_tries`` times, and not after
``max_age_s`` since it was queued; then it goes to the dead letters (``csws webhooks dead-letters``).
With the defaults an event is tried 8 times over about two minutes (1 + 2 + 4 + ... + 64 s, halved at
worst by the jitter), for a receiver down for a deploy or a restart.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

__all__ = ["RetryPolicy"]


@dataclass(frozen=True)
class RetryPolicy:
    """How failed deliveries are retried (see the module).

    Attributes
    ----------
    max_tries
        Tries of an event before it is a dead letter (2 or more).
    max_age_s
        Time since it was queued after which an event that failed again is a dead letter, s.
    first_delay_s, max_delay_s
        The wait after the first failure, and the longest wait, s (before jitter).
    timeout_s
        How long one delivery may take (connecting, sending, the answer), s.
    """

    max_tries: int = 8
    max_age_s: float = 24 * 3600.0
    first_delay_s: float = 1.0
    max_delay_s: float = 300.0
    timeout_s: float = 5.0

    def __post_init__(self) -> None:
        if self.max_tries < 2 or min(self.max_age_s, self.first_delay_s, self.max_delay_s, self.timeout_s) <= 0:
            raise ValueError("a retry policy needs max_tries >= 2 and positive times")

    def delay_s(self, tries: int, rng: random.Random) -> float:
        """The wait after the ``tries``-th failure, with jitter, s."""
        return min(self.first_delay_s * 2 ** (tries - 1), self.max_delay_s) * rng.uniform(0.5, 1.0)

    def gives_up(self, tries: int, queued_s: float, now_s: float) -> bool:
        """Whether an event queued at ``queued_s`` that failed its ``tries``-th try is a dead letter now."""
        return tries >= self.max_tries or now_s - queued_s >= self.max_age_s
