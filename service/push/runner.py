"""The thread that runs one dispatcher: it holds the lease, steps, and waits when there is nothing to do."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from .lease import Lease, LeaseLost

__all__ = ["Runner", "POLL_S"]

logger = logging.getLogger("csws.push")

#: How often an idle dispatcher looks for new events, s: the most an event waits in the outbox when idle.
POLL_S = 0.01


class Runner:
    """Run ``step`` in a thread of its own while ``lease`` is held, until :meth:`stop`.

    Parameters
    ----------
    name
        The thread's name.
    lease
        The lease to hold; a dispatcher without it tries again every third of its duration.
    step
        One step of delivery: the wait before the next, s (None: the poll interval).
    poll_s
        The wait when there was nothing to do, s.
    on_lease_lost
        Called when the lease goes (or is given up): to set the gauges of a dispatcher that no longer delivers.
    """

    def __init__(
        self,
        name: str,
        lease: Lease,
        step: Callable[[], float | None],
        poll_s: float = POLL_S,
        on_lease_lost: Callable[[], None] | None = None,
    ) -> None:
        self.lease, self.step, self.poll_s, self.on_lease_lost = lease, step, poll_s, on_lease_lost
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> Runner:
        """Start the thread."""
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 30.0) -> None:
        """Stop after the step under way, give the lease up, and wait for the thread."""
        self._stopping.set()
        self._thread.join(timeout_s)

    def _run(self) -> None:
        """Step while holding the lease; a failed step is logged and tried again after the poll interval."""
        try:
            while not self._stopping.is_set():
                if not self.lease.current():
                    self._lost()
                    self._stopping.wait(self.lease.duration_s / 3)
                    continue
                self._stopping.wait(self._step_once())
        finally:
            self.lease.release()
            self._lost()

    def _step_once(self) -> float:
        """One step; the wait before the next, s."""
        try:
            wait_s = self.step()
        except LeaseLost as lost:
            logger.info("%s", lost)
            return 0.0
        except Exception:  # a store or file in trouble: log, and try again
            logger.exception("push: a step of delivery failed")
            return max(self.poll_s, 1.0)
        return self.poll_s if wait_s is None else wait_s

    def _lost(self) -> None:
        if self.on_lease_lost is not None:
            self.on_lease_lost()
