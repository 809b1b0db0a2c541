"""The JT/T 808 gateway's groups (service.jt808_groups.Batcher) on a real work thread: reports that keep coming
are answered in groups started at most once a window, every one of them, in order, whatever the rate."""

from __future__ import annotations

import asyncio
import math
import time
from types import SimpleNamespace
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from service.jt808_groups import AnswerSummary, Batcher, Waiting
from service.work import WorkThread


class CountingService:
    """A warning service that answers each query at level 0 after ``cost_s`` of work, and notes each group's size
    and start (``time.monotonic``, on the work thread) and when the first report was queued."""

    def __init__(self, cost_s: float) -> None:
        self.cost_s = cost_s
        self.groups: list[tuple[float, int]] = []
        self.first_queued_s = math.nan

    def answer(self, queries: list[Any], **_: Any) -> SimpleNamespace:
        self.groups.append((time.monotonic(), len(queries)))
        time.sleep(self.cost_s)
        documents = [SimpleNamespace(target=None) for _ in queries]
        return SimpleNamespace(
            state=[SimpleNamespace(value="active")] * len(queries),
            level=[0] * len(queries),
            documents=documents,
            warning_speed_kmh=[None] * len(queries),
            placement=[None] * len(queries),
        )


def _run(window_s: float, gap_s: float, count: int, cost_s: float) -> tuple[CountingService, list[str], float]:
    """``count`` reports queued ``gap_s`` apart; the service, the vehicles answered in order, and how long the
    reports kept coming, s."""
    service = CountingService(cost_s)
    answered: list[str] = []

    async def run() -> float:
        batcher = Batcher(service, WorkThread("test-groups"), window_s)  # type: ignore[arg-type]
        done = asyncio.Event()
        first_s = time.monotonic()

        def deliver(vehicle_id: str):
            def take(answer: AnswerSummary | None) -> None:
                assert answer is not None and answer.level == 0
                answered.append(vehicle_id)
                if len(answered) == count:
                    done.set()

            return take

        service.first_queued_s = time.monotonic()
        for k in range(count):
            query = SimpleNamespace(vehicle_id=f"v{k}")
            batcher.queue(Waiting(query, "fleet", deliver(f"v{k}")))  # type: ignore[arg-type]
            await asyncio.sleep(gap_s)
        arriving_s = time.monotonic() - first_s
        await asyncio.wait_for(done.wait(), 30.0)
        return arriving_s

    return service, answered, asyncio.run(run())


@settings(max_examples=8, deadline=None)
@given(window_ms=st.integers(5, 30), gap_ms=st.sampled_from([0.0, 0.5, 2.0]), cost_ms=st.sampled_from([0.0, 3.0]))
def test_groups_start_at_most_once_a_window_and_answer_every_report_in_order(window_ms, gap_ms, cost_ms) -> None:
    count = 120
    service, answered, arriving_s = _run(window_ms / 1000.0, gap_ms / 1000.0, count, cost_ms / 1000.0)
    assert answered == [f"v{k}" for k in range(count)]
    assert sum(size for _, size in service.groups) == count
    # One group at the first window's end, then at most one a window while reports keep coming, and one for
    # those that came during the last.
    assert len(service.groups) <= arriving_s / (window_ms / 1000.0) + 2


def test_a_lone_report_is_answered_after_one_window() -> None:
    window_s = 0.02
    service, answered, _ = _run(window_s, 0.0, 1, 0.0)
    assert answered == ["v0"] and [size for _, size in service.groups] == [1]
    # Its group waited the window for others (less the event loop's clock resolution) before it started.
    assert service.groups[0][0] - service.first_queued_s >= window_s - 1e-3


def test_without_a_window_reports_that_meet_during_an_evaluation_go_next_at_once() -> None:
    service, answered, _ = _run(0.0, 0.001, 50, 0.005)
    assert len(answered) == 50 and len(service.groups) > 1
