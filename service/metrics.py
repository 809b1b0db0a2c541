"""Prometheus metrics of the service: requests, latencies and warnings by level.

A small text-format exposition (version 0.0.4) with no dependency: counters of
requests by route and status, a latency histogram by route, and counters of the
answers by system state and warning level. :class:`MetricsMiddleware` is a plain ASGI
middleware, so measuring costs next to nothing per request.
"""

from __future__ import annotations

import bisect
import time
from collections import Counter, defaultdict
from collections.abc import Iterable
from itertools import accumulate
from typing import Any

__all__ = ["LATENCY_BUCKETS_S", "Metrics", "MetricsMiddleware"]

#: Upper bounds of the latency histogram's buckets, s.
LATENCY_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)


def _labels(**labels: Any) -> str:
    return ",".join(f'{name}="{str(value)}"' for name, value in labels.items())


class Metrics:
    """The counters and histograms, and their exposition."""

    def __init__(self) -> None:
        self.requests: dict[tuple[str, str, int], int] = defaultdict(int)
        #: Per route, the requests of each latency bucket alone (the last: above every bound);
        #: the exposition adds them up into Prometheus' cumulative buckets.
        self.latency_buckets: dict[str, list[int]] = defaultdict(lambda: [0] * (len(LATENCY_BUCKETS_S) + 1))
        self.latency_sum_s: dict[str, float] = defaultdict(float)
        self.latency_count: dict[str, int] = defaultdict(int)
        self.answers: dict[tuple[str, int], int] = defaultdict(int)

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Count a request and its latency."""
        self.requests[(method, route, status)] += 1
        self.latency_buckets[route][bisect.bisect_left(LATENCY_BUCKETS_S, seconds)] += 1
        self.latency_sum_s[route] += seconds
        self.latency_count[route] += 1

    def observe_answers(self, states: Iterable[str], levels: Iterable[int]) -> None:
        """Count answers by system state and warning level (parallel sequences)."""
        for key, count in Counter(zip(states, levels, strict=False)).items():
            self.answers[key] += count

    def exposition(self) -> str:
        """The metrics in Prometheus' text format."""
        lines = [
            "# HELP csws_http_requests_total HTTP requests by method, route and status.",
            "# TYPE csws_http_requests_total counter",
        ]
        for (method, route, status), count in sorted(self.requests.items()):
            lines.append(f"csws_http_requests_total{{{_labels(method=method, route=route, status=status)}}} {count}")
        lines += [
            "# HELP csws_http_request_duration_seconds Time to answer an HTTP request.",
            "# TYPE csws_http_request_duration_seconds histogram",
        ]
        for route in sorted(self.latency_count):
            for bound, count in zip(LATENCY_BUCKETS_S, accumulate(self.latency_buckets[route]), strict=False):
                lines.append(f"csws_http_request_duration_seconds_bucket{{{_labels(route=route, le=bound)}}} {count}")
            lines.append(
                f"csws_http_request_duration_seconds_bucket{{{_labels(route=route, le='+Inf')}}} "
                f"{self.latency_count[route]}"
            )
            lines.append(
                f"csws_http_request_duration_seconds_sum{{{_labels(route=route)}}} {self.latency_sum_s[route]}"
            )
            lines.append(
                f"csws_http_request_duration_seconds_count{{{_labels(route=route)}}} {self.latency_count[route]}"
            )
        lines += [
            "# HELP csws_answers_total Answers given, by system state and warning level.",
            "# TYPE csws_answers_total counter",
        ]
        for (state, level), count in sorted(self.answers.items()):
            lines.append(f"csws_answers_total{{{_labels(state=state, level=level)}}} {count}")
        return "\n".join(lines) + "\n"


#: The HTTP methods counted under their own name.
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "DELETE", "PATCH", "OPTIONS"})


class MetricsMiddleware:
    """ASGI middleware that counts every HTTP request and times it.

    Requests are labelled by their route template (``/v1/vehicles/{vehicle_id}``), not
    the raw path, and by their method, any but the standard ones (:data:`METHODS`) as
    ``other``, so the number of series stays bounded whatever clients send.
    """

    def __init__(self, app, metrics: Metrics) -> None:
        self.app = app
        self.metrics = metrics

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        status = 500

        async def send_with_status(message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, send_with_status)
        finally:
            route = scope.get("route")
            template = getattr(route, "path", None) or "unmatched"
            method = scope["method"] if scope["method"] in METHODS else "other"
            self.metrics.observe_request(method, template, status, time.perf_counter() - started)
