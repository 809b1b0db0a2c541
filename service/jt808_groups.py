"""The JT/T 808 gateway's groups: the reports of all connections answered together on the work thread.

A report's query is queued as its report is read and answered in the next group; its answer is
handed to the callback it came with, on the event loop, in the turn that learns the group is done.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Sequence
from typing import NamedTuple

from csws.gateways.jt808.latency import StageTimes
from csws.standard import Category
from csws.state import SystemState

from .answers import WarningService
from .checks import QueryErrors
from .decoding import DecodedQuery
from .guard import OncePerInterval
from .jt808_tracking import TrackingPlanner
from .placement import Placement
from .store import StoreUnavailable
from .timing import Stages
from .work import WorkThread

__all__ = ["AnswerSummary", "Batcher", "Waiting"]

log = logging.getLogger("csws.jt808.groups")
log.addFilter(OncePerInterval())


class AnswerSummary(NamedTuple):
    """What the driver may be told of an answer: its system state, level, the target's V_w (None without one), and
    how long to ask its terminal for temporary tracking, s (None: not now; :mod:`service.jt808_tracking`). A named
    tuple: one is made for every report."""

    state: str
    level: int
    warning_speed_kmh: float | None
    tracking_window_s: int | None = None


#: One report of a group as the work thread takes it: the query, its fleet, and the terminal's regular intervals
#: when the report is to be checked for temporary tracking (None: not).
Item = tuple[DecodedQuery, str, tuple[float, ...] | None]


class Waiting:
    """A query waiting for its group, and what to do with its answer.

    Attributes
    ----------
    deliver
        Called on the event loop with the answer (None when it could not be answered), as soon as
        its group is done.
    intervals_s
        The terminal's regular report intervals when the report is to be checked for temporary
        tracking (:meth:`csws.gateways.jt808.tracking.ReportPace.due`), else None.
    queued_at
        When it was queued (``time.perf_counter``).
    started, shed
        Whether its group has started; whether it was withdrawn before that (it is then skipped).
    """

    __slots__ = ("query", "fleet", "deliver", "intervals_s", "queued_at", "started", "shed")

    def __init__(
        self,
        query: DecodedQuery,
        fleet: str,
        deliver: Callable[[AnswerSummary | None], None],
        intervals_s: tuple[float, ...] | None = None,
    ) -> None:
        self.query, self.fleet, self.deliver, self.intervals_s = query, fleet, deliver, intervals_s
        self.queued_at, self.started, self.shed = time.perf_counter(), False, False


class Batcher:
    """Answers the queries of all connections in groups, one group on the work thread at a time.

    A query is queued as its report is read, and its answer delivered by the callback it came with in
    the same turn of the event loop that learns its group is done: no task per report stands between
    the work thread and the ``0x8300``. A group starts at most every ``window_s``: the first query
    after an idle spell waits that long for others, and the queries that arrive while a group is
    evaluated go next once ``window_s`` has passed since that group started (at once if it took
    longer). A group's fixed cost (the store's round trips, the matcher's and engine's set-up: a few
    milliseconds) is thereby paid at most once a window however many terminals report, instead of
    once for every handful of reports that met during the last evaluation.

    Each query's time is counted in ``times``: ``wait`` from queued to its group's start on the work
    thread, ``evaluate`` its group's evaluation, ``handback`` from there to the event loop; and each
    group's stages of the warning service (``group:read``, ``group:match``, ... ``group:write``) once
    per query.
    """

    def __init__(
        self,
        service: WarningService,
        work: WorkThread,
        window_s: float = 0.0,
        times: StageTimes | None = None,
        planner: TrackingPlanner | None = None,
    ) -> None:
        self.service, self.work, self.window_s, self.planner = service, work, window_s, planner
        self.times = times if times is not None else StageTimes()
        self._waiting: list[Waiting] = []
        self._running = False

    def queue(self, waiting: Waiting) -> None:
        """Queue ``waiting`` for the next group (at most one starts every window)."""
        self._waiting.append(waiting)
        if not self._running:
            self._running = True
            asyncio.get_running_loop().create_task(self._drain())

    async def _drain(self) -> None:
        loop = asyncio.get_running_loop()
        try:
            await asyncio.sleep(self.window_s)
            while self._waiting:
                group_started_s = loop.time()
                group = [waiting for waiting in self._waiting if not waiting.shed]
                self._waiting = []
                if not group:
                    continue
                for waiting in group:
                    waiting.started = True
                try:
                    answers, timed = await self.work.run(
                        self.answer_group, [(w.query, w.fleet, w.intervals_s) for w in group]
                    )
                    self._count(group, *timed)
                except Exception:  # noqa: BLE001 - a fault of one group must not stop the gateway
                    log.exception("jt808: a group of %d reports was not answered", len(group))
                    answers = [None] * len(group)
                for waiting, answer in zip(group, answers, strict=True):
                    waiting.deliver(answer)
                rest_s = self.window_s - (loop.time() - group_started_s)
                if self._waiting and rest_s > 0:
                    await asyncio.sleep(rest_s)
        finally:
            self._running = False

    def _count(self, group: list[Waiting], started: float, ended: float, stages: Stages) -> None:
        """Count the group's wait, evaluation, hand-back and service stages, once per query."""
        now, times = time.perf_counter(), self.times
        for waiting in group:
            times.add("wait", started - waiting.queued_at)
        times.add("evaluate", ended - started, len(group))
        times.add("handback", now - ended, len(group))
        for name, milliseconds in stages.milliseconds.items():
            times.add(f"group:{name}", milliseconds / 1000.0, len(group))

    def answer_group(
        self, group: Sequence[Item], stages: Stages | None = None
    ) -> tuple[list[AnswerSummary | None], tuple[float, float, Stages]]:
        """Each query's answer, fleet by fleet (on the work thread; one that fails alone is None), and when the
        group started and ended with the time of its stages (counted in ``stages``, new ones by default)."""
        started, stages = time.perf_counter(), stages if stages is not None else Stages()
        fleets = {fleet for _, fleet, _ in group}
        if len(fleets) == 1:  # the usual case: one fleet per gateway, no regrouping
            return self._answer_fleet(group, fleets.pop(), stages), (started, time.perf_counter(), stages)
        answers: list[AnswerSummary | None] = [None] * len(group)
        for fleet in fleets:
            indices = [i for i, (_, f, _) in enumerate(group) if f == fleet]
            fleet_answers = self._answer_fleet([group[i] for i in indices], fleet, stages)
            for index, answer in zip(indices, fleet_answers, strict=True):
                answers[index] = answer
        return answers, (started, time.perf_counter(), stages)

    def _answer_fleet(self, items: Sequence[Item], fleet: str, stages: Stages) -> list[AnswerSummary | None]:
        queries = [query for query, _, _ in items]
        try:
            answers = self.service.answer(
                queries, loc=("jt808",), fleet=fleet, stages=stages, documents=False, fleet_category_first=True
            )
        except QueryErrors as errors:
            if len(items) > 1:
                return [answer for item in items for answer in self._answer_fleet([item], fleet, stages)]
            log.warning("jt808: report of %s not answered: %s", queries[0].vehicle_id, _first_error(errors))
            return [None]
        except StoreUnavailable as error:
            log.warning("jt808: state store unavailable: %s", error)
            return [None] * len(items)
        windows: list[int | None] = [None] * len(items)
        due = [(row, query, intervals_s) for row, (query, _, intervals_s) in enumerate(items) if intervals_s]
        planner = self.planner
        if due and planner is not None:
            with stages("tracking"):
                for row, query, intervals_s in due:
                    windows[row] = _tracking_window_s(
                        planner,
                        query,
                        answers.category[row],
                        answers.state[row],
                        answers.placement[row],
                        intervals_s,
                        fleet,
                    )
        return [
            AnswerSummary(str(state.value), int(level), warning_speed_kmh, window_s)
            for state, level, warning_speed_kmh, window_s in zip(
                answers.state, answers.level, answers.warning_speed_kmh, windows, strict=True
            )
        ]


def _tracking_window_s(
    planner: TrackingPlanner,
    query: DecodedQuery,
    category: Category | None,
    state: SystemState,
    placement: Placement | None,
    intervals_s: Sequence[float],
    fleet: str,
) -> int | None:
    """The tracking window a report of ``fleet`` asks for (None: none), where a fault of the planner costs only the
    request, never the report's answer: temporary tracking is advice, the warning is not."""
    try:
        return planner.window_s(query, category, state, placement, intervals_s, fleet)
    except Exception:  # noqa: BLE001 - one report's tracking must not take its group's answers with it
        log.exception("jt808: no tracking window for %s", query.vehicle_id)
        return None


def _first_error(errors: QueryErrors) -> str:
    """The first problem QueryErrors names."""
    return str(errors.errors[0]["msg"]) if errors.errors else str(errors)
