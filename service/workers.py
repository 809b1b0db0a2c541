"""The workers of ``csws serve --workers N``: they leave when their master is gone."""

from __future__ import annotations

import os
import signal
import threading
import time

__all__ = ["MASTER_PID_VARIABLE", "MASTER_CHECK_S", "leave_with_master"]

#: Set by ``csws serve --workers N`` for its workers: the process id of the master.
MASTER_PID_VARIABLE = "CSWS_MASTER_PID"
#: How often a worker looks whether its master is still there, s.
MASTER_CHECK_S = 1.0


def leave_with_master() -> None:
    """In a worker of ``csws serve --workers N``: end this process when the master is gone.

    A master killed with SIGKILL cannot stop its workers, and they would go on serving, the
    port taken, with nobody to restart or stop them. Each worker checks every
    :data:`MASTER_CHECK_S` whether its parent is still the master (from its start-up on, so
    that one still starting when the master died leaves too), and otherwise shuts down as
    on SIGTERM. Outside such a worker (no master recorded) nothing is started.
    """
    master = os.environ.get(MASTER_PID_VARIABLE)
    if not master:
        return
    # A worker still starting when its master was killed finds another parent at once, and leaves.

    def watch() -> None:
        while os.getppid() == int(master):
            time.sleep(MASTER_CHECK_S)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(3.0)
        os._exit(1)  # the graceful shutdown did not end it

    threading.Thread(target=watch, name="csws-master-watch", daemon=True).start()
