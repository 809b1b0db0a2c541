"""The gateway's stage times and the scale-out bound, against values the tests compute themselves."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from csws.gateways.jt808.latency import StageTimes, parse_stages

# The benchmarks are run from the repository, not installed: import them from there.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.jt808 import scaleout_bound, summary_counts  # noqa: E402

seconds = st.floats(min_value=0.0, max_value=5.0, allow_nan=False)


def _nearest_rank_bounds(values_ms: list[float], q: float) -> tuple[float, float]:
    """The two order statistics an interpolated ``q`` percentile lies between."""
    ordered = sorted(values_ms)
    position = q / 100.0 * (len(ordered) - 1)
    return ordered[math.floor(position)], ordered[math.ceil(position)]


@given(st.lists(seconds, min_size=1, max_size=200), st.lists(seconds, min_size=1, max_size=50))
def test_the_printed_line_reads_back_as_each_stages_percentiles(waits_s, texts_s):
    times = StageTimes()
    for wait_s in waits_s:
        times.add("wait", wait_s)
    for text_s in texts_s:
        times.add("text", text_s)
    read = parse_stages(f"csws: JT/T 808 gateway stopped: ...\ncsws: {times.line()}\n")
    assert list(read) == ["wait", "text"]
    for name, samples_s in (("wait", waits_s), ("text", texts_s)):
        for q, value_ms in zip((50.0, 99.0), read[name], strict=True):
            low_ms, high_ms = _nearest_rank_bounds([s * 1000.0 for s in samples_s], q)
            assert low_ms - 0.05 <= value_ms <= high_ms + 0.05  # printed to 0.1 ms


def test_a_group_counts_once_per_report_and_old_samples_are_forgotten():
    times = StageTimes(keep=100)
    times.add("evaluate", 1.0, count=99)
    times.add("evaluate", 0.0)
    assert times.percentiles_ms("evaluate", (1.0, 50.0)) == (990.0, 1000.0)  # 1 of 100 samples is 0
    times.add("evaluate", 0.002, count=100)  # the older 100 are gone
    assert times.percentiles_ms("evaluate", (0.0, 100.0)) == (2.0, 2.0)
    assert all(math.isnan(value) for value in times.percentiles_ms("never"))
    assert parse_stages("no stages here") == {}


def _run(rate: float, gateway_cores: float, redis_cores: float, simulator_cores: float) -> dict[str, float]:
    return {
        "evaluated_per_s": rate,
        "gateway_cores": gateway_cores,
        "redis_cores": redis_cores,
        "simulator_cores": simulator_cores,
    }


def test_the_bound_is_the_cores_left_over_what_one_gateway_needed():
    # One gateway: 1000 reports/s on 0.9 cores, Redis 0.1; the terminals take 0.6 of 2 cores.
    one = _run(1000.0, 0.9, 0.1, 0.6)
    # Each report costs 1 ms of CPU in all; 1.4 cores left evaluate at most 1400/s: 1.4 times one.
    assert math.isclose(scaleout_bound(one, _run(1200.0, 1.1, 0.1, 0.5), cores=2), 1.4)
    # Where the cores suffice, two single-threaded gateways at most double it.
    assert scaleout_bound(one, one, cores=8) == 2.0


@given(
    st.floats(100.0, 5000.0),
    st.floats(0.1, 1.0),
    st.floats(0.0, 0.3),
    st.floats(0.0, 1.5),
    st.floats(0.0, 0.4),
)
def test_the_bound_falls_as_the_terminals_take_more_of_the_cores(rate, gateway_cores, redis_cores, simulator, more):
    one = _run(rate, gateway_cores, redis_cores, simulator)
    bound = scaleout_bound(one, one, cores=2)
    assert bound <= 2.0
    heavier = _run(rate, gateway_cores, redis_cores, simulator + more)
    assert scaleout_bound(one, heavier, cores=2) <= bound + 1e-12


def test_the_benchmark_reads_the_counts_of_the_gateways_summary_line_and_refuses_output_without_one():
    # The summary's wording, as test_jt808_conversation holds Gateway.summary to it.
    summary = "3 connection(s), 3558 report(s) evaluated, 2526 shed, 12 text(s) told, 0 tracking request(s), 1 ..."
    assert summary_counts(f"jt808: a log line of 13900000001 shed\n{summary}\n") == (3558, 2526)
    with pytest.raises(RuntimeError, match="without its summary line"):
        summary_counts("Traceback (most recent call last):")
