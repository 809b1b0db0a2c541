"""The lease that lets one dispatcher of each kind deliver at a time, among workers and replicas.

Every worker may run a dispatcher; each tries to hold the lease
(:meth:`service.push.state.PushStore.hold_lease`), and only the holder delivers. The holder renews it
while it works, at least every third of its duration; a dispatcher that stops gives it up, one that
dies lets it expire, and another takes over then. So each event goes out once per sink in normal
operation, and at least once across a crash: a holder that loses the lease stops before its next
delivery (:class:`LeaseLost`), and its successor starts again from the durable cursor.
"""

from __future__ import annotations

import os
import socket
import time
import uuid
from collections.abc import Callable

from .state import PushStore

__all__ = ["LEASE_S", "Lease", "LeaseLost"]

#: How long a lease lasts without renewal, s: a dead holder's successor takes over within this.
LEASE_S = 10.0


class LeaseLost(RuntimeError):
    """Another dispatcher holds the lease now: stop delivering."""


class Lease:
    """One dispatcher's hold on the lease ``name``.

    Parameters
    ----------
    state
        Where the lease is kept.
    name
        The lease: one per kind of sink (``webhooks``, ``mqtt``).
    duration_s
        How long it lasts without renewal.
    clock
        Unix seconds.
    """

    def __init__(
        self, state: PushStore, name: str, duration_s: float = LEASE_S, clock: Callable[[], float] = time.time
    ) -> None:
        self.state, self.name, self.duration_s, self.clock = state, name, duration_s, clock
        self.holder = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._renewed_s = -float("inf")
        self.held = False

    def hold(self) -> bool:
        """Take or renew the lease now; whether this dispatcher holds it."""
        now_s = self.clock()
        self.held = self.state.hold_lease(self.name, self.holder, now_s, self.duration_s)
        self._renewed_s = now_s if self.held else -float("inf")
        return self.held

    def current(self) -> bool:
        """Whether this dispatcher holds the lease, renewing it once a third of it has passed."""
        if self.held and self.clock() - self._renewed_s < self.duration_s / 3:
            return True
        return self.hold()

    def keep(self) -> None:
        """Before a delivery: :meth:`current`, or :class:`LeaseLost` when the lease went to another dispatcher."""
        if not self.current():
            raise LeaseLost(f"the {self.name} lease went to another dispatcher")

    def release(self) -> None:
        """Give the lease up, if held."""
        if self.held:
            self.state.release_lease(self.name, self.holder)
            self.held = False
