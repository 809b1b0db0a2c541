"""The telematics benchmark's pure helpers on constructed data: sampling, GNSS noise, onsets, their
pairing with the reference's, repeats, and the share of fixes matched to the road truly driven."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

# The benchmarks are run from the repository, not installed: import them from there.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.telematics import (  # noqa: E402
    EXACT_POSITIONS_1_HZ,
    EXACT_RECEIVER_1_HZ,
    PRECISE_POSITIONS_1_HZ,
    SIGMA_3_1_HZ,
)
from benchmarks.telematics_analysis import (  # noqa: E402
    Noise,
    match_onsets,
    noisy_fixes,
    on_at,
    onsets,
    repeat_onsets,
    sample_mask,
)
from benchmarks.telematics_feed import (  # noqa: E402
    AnswersRead,
    FeedAnswers,
    QueryFields,
    feed_columns,
    feed_fixes,
    feed_rows,
    read_answers,
)
from benchmarks.telematics_fleet import Trajectories  # noqa: E402
from benchmarks.telematics_judge import judge  # noqa: E402


def test_each_vehicle_reports_every_interval_in_its_own_phase() -> None:
    steps = np.tile(np.arange(200), 5)
    vehicles = np.repeat(np.arange(5), 200)
    mask = sample_mask(steps, vehicles, interval_steps=50, batch_steps=10)
    for vehicle in range(5):
        expected = [10 * vehicle + 50 * k for k in range(4)]
        assert steps[mask & (vehicles == vehicle)].tolist() == expected
    # every batch instant carries exactly one of the five vehicles: the fleet spread evenly
    assert np.bincount(steps[mask] // 10, minlength=20).tolist() == [1] * 20
    assert steps[sample_mask(steps, vehicles, interval_steps=10, batch_steps=10) & (vehicles == 3)].tolist() == list(
        range(0, 200, 10)
    )
    with pytest.raises(ValueError, match="whole number of batches"):
        sample_mask(steps, vehicles, interval_steps=15, batch_steps=10)


def test_noise_has_the_receivers_spread_and_drop_share() -> None:
    count = 200_000
    noise = Noise(position_sigma_m=3.0, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.02)
    x_m, y_m = np.linspace(0.0, 1000.0, count), np.full(count, 50.0)
    heading_deg, speed_kmh = np.full(count, 90.0), np.full(count, 40.0)
    fixes = noisy_fixes(x_m, y_m, heading_deg, speed_kmh, noise, np.random.default_rng(7))
    kept = fixes.kept.sum()
    # the share dropped within four standard errors of a binomial share
    assert abs(1.0 - kept / count - 0.02) <= 4.0 * np.sqrt(0.02 * 0.98 / count)
    # the sample standard deviations within 3 % (their standard error is sigma / sqrt(2 n), about 0.16 %)
    assert np.std(fixes.x_m - x_m[fixes.kept]) == pytest.approx(3.0, rel=0.03)
    assert np.std(fixes.y_m - y_m[fixes.kept]) == pytest.approx(3.0, rel=0.03)
    assert np.std(fixes.heading_deg - 90.0) == pytest.approx(5.0, rel=0.03)
    assert np.std(fixes.speed_kmh - 40.0) == pytest.approx(0.5, rel=0.03)
    again = noisy_fixes(x_m, y_m, heading_deg, speed_kmh, noise, np.random.default_rng(7))
    assert np.array_equal(again.x_m, fixes.x_m) and np.array_equal(again.kept, fixes.kept)


@given(st.floats(0.0, 359.999), st.floats(0.0, 3.0))
def test_noisy_headings_stay_in_a_turn_and_speeds_stay_positive(heading_deg: float, speed_kmh: float) -> None:
    noise = Noise(position_sigma_m=8.0, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.0)
    fixes = noisy_fixes(
        np.zeros(50), np.zeros(50), np.full(50, heading_deg), np.full(50, speed_kmh), noise, np.random.default_rng(1)
    )
    assert np.all((fixes.heading_deg >= 0.0) & (fixes.heading_deg < 360.0))
    assert np.all(fixes.speed_kmh >= 0.0)
    # the wrapped heading is within 30 deg (six sigma) of the true one around the circle
    assert np.all(np.abs((fixes.heading_deg - heading_deg + 180.0) % 360.0 - 180.0) < 30.0)


def test_onsets_are_the_answers_where_a_warning_comes_on() -> None:
    assert onsets(np.array([0, 1, 1, 0, 2, 0, 0, 1])).tolist() == [1, 4, 7]
    assert onsets(np.array([2, 1, 0, 1])).tolist() == [0, 3]
    assert onsets(np.array([], dtype=int)).tolist() == []


def test_feed_onsets_pair_with_the_reference_within_the_window_once_each() -> None:
    reference_s = np.array([10.0, 11.0, 50.0, 100.0])
    feed_s = np.array([9.0, 53.0, 200.0])
    match = match_onsets(reference_s, feed_s, before_s=1.0, after_s=3.0)
    # 9 s is the first reference onset's (1 s early, the window's edge), not also the second's
    assert match.pairs == [(0, 0), (2, 1)]
    assert match.unmatched_reference == [1, 3]
    assert match.unmatched_feed == [2]


def test_repeat_onsets_count_warnings_switched_off_and_on_within_the_gap() -> None:
    times_s = np.arange(11.0)
    levels = np.array([1, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0])
    # onsets at 0 s (no warning before), 3 s (2 s after the one at 1 s: a repeat), 8 s (5 s after 3 s)
    assert repeat_onsets(times_s, levels, gap_s=3.0) == 1
    assert repeat_onsets(times_s, levels, gap_s=5.0) == 2
    assert on_at(times_s, levels, 4.0, 7.0) is False and on_at(times_s, levels, 4.0, 8.0) is True


def _straight_run(lanes: list[str], steps_per_lane: int, speed_mps: float) -> Trajectories:
    """One vehicle driving through ``lanes`` in turn at a constant speed, one lane every ``steps_per_lane``."""
    count = len(lanes) * steps_per_lane
    step = np.arange(count)
    return Trajectories(
        step=step,
        vehicle=np.zeros(count, dtype=np.int64),
        x_m=speed_mps * 0.1 * step,
        y_m=np.zeros(count),
        speed_mps=np.full(count, speed_mps),
        heading_deg=np.full(count, 90.0),
        lane=step // steps_per_lane,
        lane_pos_m=speed_mps * 0.1 * (step % steps_per_lane),
        vehicle_ids=["truck0"],
        categories=["N"],
        lanes=lanes,
    )


def test_the_receivers_speeds_and_drops_on_exact_lanes_are_those_the_sigma_3_m_feed_sends() -> None:
    trajectories = _straight_run(["A_0", ":J_0_0", "B_0", "C_0"], 500, 12.0)
    rows = feed_rows(trajectories, 1.0)
    assert SIGMA_3_1_HZ.noise is not None
    sent_rows, fixes = feed_fixes(trajectories, rows, SIGMA_3_1_HZ.noise, SIGMA_3_1_HZ.seed)
    kept, columns, accuracy = feed_columns(Path("unused.net.xml"), trajectories, EXACT_RECEIVER_1_HZ, QueryFields(None))
    # the same fixes survive, with the same measured speeds, but each is sent as its exact lane and position
    assert len(kept) < len(rows) and kept.tolist() == sent_rows.tolist()
    assert columns["speed_kmh"] == fixes.speed_kmh.tolist()
    assert columns["lane_id"] == [trajectories.lanes[row // 500] for row in kept.tolist()]
    assert columns["lane_pos_m"] == pytest.approx([1.2 * (row % 500) for row in kept.tolist()])
    assert "position" not in columns and accuracy is None
    assert EXACT_RECEIVER_1_HZ.noise is not None and not EXACT_RECEIVER_1_HZ.sends_positions


@pytest.mark.parametrize(("feed", "accuracy_m"), [(EXACT_POSITIONS_1_HZ, 3.0), (PRECISE_POSITIONS_1_HZ, 0.5)])
def test_exact_positions_are_sent_with_the_sigma_3_m_receivers_speeds_and_drops(
    tmp_path: Path, feed, accuracy_m: float
) -> None:
    trajectories = _straight_run(["A_0", ":J_0_0", "B_0", "C_0"], 500, 12.0)
    rows = feed_rows(trajectories, 1.0)
    assert SIGMA_3_1_HZ.noise is not None
    sent_rows, fixes = feed_fixes(trajectories, rows, SIGMA_3_1_HZ.noise, SIGMA_3_1_HZ.seed)
    # a network without a projection: positions go as network x/y
    net = tmp_path / "plain.net.xml"
    net.write_text('<net><location netOffset="0.00,0.00" convBoundary="0,0,100,0" projParameter="!"/></net>')
    kept, columns, accuracy = feed_columns(net, trajectories, feed, QueryFields("query"))
    # the same fixes survive with the same measured speeds, each sent at its true position and heading with the
    # accuracy the feed claims: the service matches them with that accuracy, without a position error
    assert kept.tolist() == sent_rows.tolist()
    assert columns["speed_kmh"] == fixes.speed_kmh.tolist()
    assert [p["x"] for p in columns["position"]] == pytest.approx([1.2 * row for row in kept.tolist()])
    assert [p["y"] for p in columns["position"]] == [0.0] * len(kept)
    assert columns["heading_deg"] == [90.0] * len(kept)
    assert "lane_id" not in columns and accuracy == ("query", accuracy_m)
    assert feed.sends_positions


def _answers(rows: list[int], levels: list[int], matched: list[str | None], target: list[str | None]) -> FeedAnswers:
    return FeedAnswers(
        rows=np.array(rows),
        level=np.array(levels, dtype=np.int8),
        matched_lane=np.array(matched, dtype=object),
        confirmed_lane=np.array(matched, dtype=object),
        target_edge=np.array(target, dtype=object),
        server_ms=2.0,
    )


def test_a_later_answers_confirmed_fix_replaces_the_earlier_fixs_lane() -> None:
    # Two vehicles; the second answer of v1 confirms its first fix on another lane (a junction fix the next fix
    # showed on the turn); v2's first fix is never confirmed and keeps its own lane.
    queries = [
        {"vehicle_id": "v1", "timestamp_s": 10.0},
        {"vehicle_id": "v2", "timestamp_s": 10.0},
        {"vehicle_id": "v1", "timestamp_s": 11.0},
    ]
    answers = [
        {"level": 0, "matched": {"lane_id": ":J_0_0"}, "target": None},
        {"level": 0, "matched": {"lane_id": "A_0"}, "target": None},
        {
            "level": 1,
            "matched": {"lane_id": "S_0"},
            "target": {"curve_id": "S_0@12.5"},
            "confirmed": {"timestamp_s": 10.0, "lane_id": ":J_1_0", "revised": True},
        },
    ]
    read = AnswersRead()
    read_answers(answers, queries, read)
    assert read.matched == [":J_0_0", "A_0", "S_0"]
    assert read.confirmed == [":J_1_0", "A_0", "S_0"]
    assert read.target == [None, None, "S_0"]


def test_a_feed_is_judged_against_the_reference_onset_by_onset() -> None:
    # 10 m/s through A (steps 0-99), a junction connection (100-199), B (200-299), C (300-399)
    trajectories = _straight_run(["A_0", ":J_0_0", "B_0", "C_0"], 100, 10.0)
    reference_levels = np.zeros(400, dtype=int)
    reference_levels[[*range(50, 80), *range(250, 280)]] = 1
    reference = _answers(list(range(400)), reference_levels.tolist(), ["A_0"] * 400, [None] * 400)
    # 1 Hz: on 1 s after the first reference onset, never for the second, and a false level 2 at the junction
    rows = list(range(0, 400, 10))
    levels = [1 if row in (60, 70) else 2 if row in (150, 160) else 0 for row in rows]
    matched: list[str | None] = [trajectories.lanes[row // 100] for row in rows]
    matched[rows.index(150)] = ":J_1_0"  # a connection the vehicle did not take
    matched[rows.index(380)] = None  # a fix that matched nothing
    matched[rows.index(300)] = "B_0"  # B was driven within 20 m before it: the true road
    matched[rows.index(320)] = "B_0"  # 21 m past B's end is not
    figures = judge(trajectories, reference, _answers(rows, levels, matched, [None] * 40), 1.0, matching=True)
    assert figures["reference_onsets"] == 2 and figures["onsets"] == 2
    assert figures["missed"] == 1 and figures["late_intervals"]["median"] == pytest.approx(1.0)
    assert (figures["false"], figures["false_level_2"], figures["false_junction"]) == (1, 1, 1)
    assert figures["false_level_2_junction"] == 1
    matching = figures["matching"]
    assert matching["true_road_share"] == pytest.approx(37 / 40)
    assert matching["no_match_share"] == pytest.approx(1 / 40)
    assert figures["us_per_fix"] == pytest.approx(2000.0 / 40)


def test_onsets_paired_in_time_but_for_another_curve_are_counted() -> None:
    # Two reference onsets, for curves starting on B and on C; the feed warns in time for both, the second for a
    # curve on D (its path ahead went elsewhere): both are paired, one of them with another curve's.
    trajectories = _straight_run(["A_0", "B_0", "C_0", "D_0"], 100, 10.0)
    reference_levels = np.zeros(400, dtype=int)
    reference_levels[[*range(50, 80), *range(250, 280)]] = 1
    reference_target: list[str | None] = [
        "B" if 50 <= row < 80 else "C" if 250 <= row < 280 else None for row in range(400)
    ]
    reference = _answers(list(range(400)), reference_levels.tolist(), ["A_0"] * 400, reference_target)
    rows = list(range(0, 400, 10))
    levels = [1 if row in (50, 60, 250, 260) else 0 for row in rows]
    target = ["B" if row in (50, 60) else "D" if row in (250, 260) else None for row in rows]
    figures = judge(trajectories, reference, _answers(rows, levels, ["A_0"] * 40, target), 1.0, matching=False)
    assert (figures["reference_onsets"], figures["onsets"], figures["missed"], figures["false"]) == (2, 2, 0, 0)
    assert figures["other_curve"] == 1
