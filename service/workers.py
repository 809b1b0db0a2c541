"""The workers of ``csws serve --workers N``: they leave when their master is gone, and their
connections answer without waiting for the client's acknowledgements."""

from __future__ import annotations

import os
import signal
import socket
import threading
import time

__all__ = ["MASTER_PID_VARIABLE", "MASTER_CHECK_S", "leave_with_master", "listen_as_tcp"]

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


def listen_as_tcp() -> None:
    """In the master of ``csws serve --workers N``, before uvicorn starts: the socket it binds for
    its workers says it is TCP, so that the workers' connections send small answers at once.

    uvicorn makes that socket with the protocol number left at 0 (uvicorn issue 3149), and
    asyncio switches Nagle's algorithm off only on connections of sockets that say they are TCP:
    every answer after the first on a keep-alive connection then waited about 40 ms for the
    client's delayed acknowledgement. The socket is made again on the same descriptor, as TCP.
    """
    import uvicorn

    bind_socket = uvicorn.Config.bind_socket

    def bind_as_tcp(config: uvicorn.Config) -> socket.socket:
        bound = bind_socket(config)
        if bound.family not in (socket.AF_INET, socket.AF_INET6) or bound.proto == socket.IPPROTO_TCP:
            return bound
        tcp = socket.socket(bound.family, bound.type, socket.IPPROTO_TCP, fileno=bound.detach())
        tcp.set_inheritable(True)
        return tcp

    uvicorn.Config.bind_socket = bind_as_tcp
