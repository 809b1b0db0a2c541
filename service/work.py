"""The thread that does the work of requests, one piece at a time in arrival order.

Queries, batches, vehicle switches (with their round trips to the state store), the curve
index and horizons run here rather than on the event loop, so that the loop keeps accepting
requests and ``/healthz`` answers while a batch of 10,000 is evaluated. The engines hold the
vehicles of one piece of work at a time: one thread, fed in arrival order, is what keeps
them apart.

A piece is handed over through a queue and its result handed back with
``loop.call_soon_threadsafe``: one wake-up each way, without the futures, locks and callbacks
an executor adds for every submission (a few tens of microseconds per query).

The cyclic garbage collector is held off while a piece of the warnings' thread runs
(``pause_gc``). A batch of 10,000 queries makes and frees hundreds of thousands of objects,
almost none of them in cycles; counted as they are made, they set off a collection every 700,
each going through every object still alive (the engines' caches of paths ahead among them):
100 to 200 ms of a batch that takes 400 ms on Bad Hersfeld. Reference counting frees them
anyway; the collections that are due run once the piece is done, over what is left.
"""

from __future__ import annotations

import asyncio
import gc
import queue
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["WorkThread"]


def _settle(done: asyncio.Future, result: Any, error: BaseException | None) -> None:
    """On the event loop: hand the result (or the error) of a piece of work to whoever awaits it."""
    if done.cancelled():
        return
    if error is not None:
        done.set_exception(error)
    else:
        done.set_result(result)


class WorkThread:
    """One thread running the pieces of work handed to :meth:`run`, in the order they were handed.

    The thread starts with the first piece, in the process that serves (a worker forked from a
    master that built the app starts its own).

    Parameters
    ----------
    name
        The thread's name.
    pause_gc
        Whether the garbage collector waits while a piece runs (the collector is the process's: one
        thread only may hold it off, the one answering the warnings).
    """

    def __init__(self, name: str = "csws-work", pause_gc: bool = True) -> None:
        self.name, self.pause_gc = name, pause_gc
        self._pieces: queue.SimpleQueue = queue.SimpleQueue()
        self._thread: threading.Thread | None = None

    async def run(self, function: Callable[..., Any], *args: Any) -> Any:
        """``function(*args)`` on the work thread, after every piece handed before it; its result.

        Raises
        ------
        Exception
            Whatever ``function`` raised.
        """
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name=self.name, daemon=True)
            self._thread.start()
        loop = asyncio.get_running_loop()
        done = loop.create_future()
        self._pieces.put((loop, done, function, args))
        return await done

    def _serve(self) -> None:
        while (piece := self._pieces.get()) is not None:
            loop, done, function, args = piece
            if self.pause_gc:
                gc.disable()
            try:
                result, error = function(*args), None
            except BaseException as raised:  # noqa: BLE001 - handed to the request that awaits it
                result, error = None, raised
            finally:
                if self.pause_gc:
                    gc.enable()
            if not loop.is_closed():  # a loop that ended meanwhile (a shutdown) awaits nothing more
                loop.call_soon_threadsafe(_settle, done, result, error)

    def close(self) -> None:
        """Let the pieces handed so far finish, then end the thread."""
        if self._thread is not None:
            self._pieces.put(None)
            self._thread.join()
            self._thread = None
