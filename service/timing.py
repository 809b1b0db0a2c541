"""Where a request's server time goes, for the ``Server-Timing`` header of a batch.

A batch reports its total (``csws;dur=``, milliseconds) and its stages: decoding the body,
reading the vehicles from the state store, checking the queries, matching the fixes, the
engines, writing the sessions back and encoding the answers. Browsers' developer tools show
them, and ``python -m benchmarks.service`` reads them from a running server.
"""

from __future__ import annotations

import time
from contextlib import AbstractContextManager, nullcontext

__all__ = ["Stages", "UNTIMED"]


class _Stage(AbstractContextManager):
    """Adds the time spent inside the ``with`` block to one stage of :class:`Stages`."""

    def __init__(self, stages: Stages, name: str) -> None:
        self.stages, self.name = stages, name

    def __enter__(self) -> _Stage:
        self.started = time.perf_counter()
        return self

    def __exit__(self, *_exc: object) -> None:
        milliseconds = self.stages.milliseconds
        milliseconds[self.name] = milliseconds.get(self.name, 0.0) + (time.perf_counter() - self.started) * 1000.0


class Stages:
    """The milliseconds of a request's stages, in the order they first ran: ``with stages("match"): ...``."""

    def __init__(self) -> None:
        self.milliseconds: dict[str, float] = {}

    def __call__(self, name: str) -> AbstractContextManager:
        return _Stage(self, name)

    def header(self, total_ms: float) -> str:
        """The ``Server-Timing`` value: the total as ``csws``, then each stage."""
        return ", ".join(f"{name};dur={ms:.3f}" for name, ms in {"csws": total_ms, **self.milliseconds}.items())


class _Untimed(Stages):
    """Stages not timed: for requests that report none (a single query)."""

    def __call__(self, name: str) -> AbstractContextManager:
        return _NOTHING


_NOTHING = nullcontext()
#: The stages of a request that reports none.
UNTIMED = _Untimed()
