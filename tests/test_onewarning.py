"""One vehicle judged in plain floats gets the batch's answer and memory to the bit."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.standard import TABLE_RADII_M, Category, Column, Level, WarningSpeedPolicy
from csws.warning.release import NOT_HELD, HeldWarning, memory_masks, next_memories
from csws.warning.rules import PathKind, WarningSettings, column_index, evaluate_batch
from csws.warning.single import judge_one

#: Radii at and beside the tables' radii, an arc of a spiral's end, and straights.
_radii = st.one_of(
    st.floats(min_value=5.0, max_value=2000.0), st.sampled_from([*TABLE_RADII_M, 39.99, 200.01, math.inf])
)
_points = st.lists(
    st.tuples(
        st.sampled_from(["a@0", "b@120"]),
        st.integers(0, 2),
        st.floats(min_value=0.0, max_value=400.0),
        _radii,
        st.booleans(),
    ),
    max_size=5,
    unique_by=lambda point: (point[0], point[1]),
)
_times = st.one_of(st.none(), st.floats(min_value=0.0, max_value=3.0))


_seconds = st.floats(min_value=0.0, max_value=2.0)


@st.composite
def _policies(draw):
    """The standard's tables, or a fleet's own: two to four radii, a speed per column, level and radius."""
    radii = sorted(draw(st.sets(st.floats(min_value=10.0, max_value=600.0), min_size=2, max_size=4)))
    speed = st.floats(min_value=5.0, max_value=160.0)
    speeds = {
        (column, level): tuple(draw(st.lists(speed, min_size=len(radii), max_size=len(radii))))
        for column in Column
        for level in (Level.LEVEL_1, Level.LEVEL_2)
    }
    return draw(st.sampled_from([WarningSpeedPolicy(), WarningSpeedPolicy(tuple(radii), speeds)]))


@st.composite
def _warning_settings(draw):
    """Warning settings with any policy, latency, g and release rule."""
    return WarningSettings(
        policy=draw(_policies()),
        update_period_s=draw(_seconds),
        system_delay_s=draw(_seconds),
        g_mps2=draw(st.floats(min_value=5.0, max_value=12.0)),
        release_margin_kmh=draw(st.floats(min_value=0.0, max_value=10.0)),
        release_hold_s=draw(st.floats(min_value=0.0, max_value=5.0)),
        release_hold_intervals=draw(st.floats(min_value=0.0, max_value=3.0)),
    )


#: A vehicle's learnt update period (None: the configured one) and its fix's age, s.
_periods = st.one_of(st.none(), st.floats(min_value=0.01, max_value=5.0))
_ages = st.one_of(st.just(0.0), st.floats(min_value=0.0, max_value=2.0))


@st.composite
def _memories(draw, points):
    """A memory naming some of the CPOIs (and perhaps one that is no longer ahead) at each level."""
    keys = [(point[0], point[1]) for point in points] + [("gone@5", 0)]
    levels = tuple(frozenset(draw(st.lists(st.sampled_from(keys), max_size=3))) for _ in range(2))
    kept = tuple(draw(_times) if level_points else None for level_points in levels)
    return draw(st.sampled_from([NOT_HELD, HeldWarning(levels, kept)]))


def _batch_judgement(speed_kmh, column, points, kind, held, now_s, warning_settings, period_s, age_s):
    """The same vehicle through :func:`evaluate_batch` and :mod:`csws.warning.release` on arrays."""
    curve_ids = [point[0] for point in points]
    parts = np.array([point[1] for point in points], dtype=np.intp)
    first = [0, len(points)]
    hold_s = [warning_settings.hold_s(period_s)]
    latched, hold = memory_masks([held], [now_s], first, curve_ids, parts, hold_s)
    batch = evaluate_batch(
        np.array([speed_kmh]),
        np.array([column]),
        np.zeros(len(points), dtype=np.intp),
        np.array([point[2] for point in points], dtype=float),
        np.array([point[3] for point in points], dtype=float),
        warning_settings,
        cpoi_latched=latched,
        cpoi_hold=hold,
        cpoi_passed=np.array([point[4] for point in points], dtype=bool),
        update_period_s=None if period_s is None else np.array([period_s]),
        age_s=np.array([age_s]),
    )
    memory = next_memories([held], [now_s], first, curve_ids, parts, batch.cpoi_rule)[0]
    return batch.vehicle_warning(0, 0, curve_ids, parts, kind), memory


@pytest.mark.slow
@settings(max_examples=800, deadline=None)
@given(
    st.data(),
    _points,
    st.floats(min_value=0.0, max_value=160.0),
    st.sampled_from(list(Category)),
    _times,
    st.sampled_from(list(PathKind)),
    _warning_settings(),
    _periods,
    _ages,
)
def test_one_vehicle_is_judged_as_in_a_batch(
    data, points, speed_kmh, category, now_s, kind, warning_settings, period_s, age_s
):
    """Any CPOIs, memory, settings, learnt update period and fix age: the same warning and memory."""
    held = data.draw(_memories(points))
    column = column_index(category)
    expected_warning, expected_memory = _batch_judgement(
        speed_kmh, column, points, kind, held, now_s, warning_settings, period_s, age_s
    )
    warning, memory = judge_one(speed_kmh, column, points, kind, held, now_s, warning_settings, period_s, age_s)
    assert warning == expected_warning
    assert (memory.points, memory.kept_at_s) == (expected_memory.points, expected_memory.kept_at_s)


def test_a_drive_through_curves_is_answered_alike_one_at_a_time_and_in_a_batch():
    """Both engines see a truck braking too late through Table 9's curves at 0.1 s: same answers,
    levels on and off, held and released."""
    truth = json.loads((networks_dir() / "t9_m1_test1_left.truth.json").read_text())
    road_map = RoadMap.load(networks_dir() / "t9_m1_test1_left.net.xml")
    single, batch = Engine(road_map), Engine(road_map)
    route = tuple(truth["route"]["edges"])
    start_s = truth["curves"][0]["start_s"] - 350.0
    s, speed_kmh, levels = start_s, 110.0, set()
    for step in range(300):
        lane = next(lane for lane in reversed(truth["lanes"]) if lane["start_s"] <= s)
        vehicle = VehicleInput(
            "truck", "N", speed_kmh, lane["lane"], s - lane["start_s"], route, timestamp_s=step * 0.1
        )
        one, [many] = single.evaluate(vehicle), batch.evaluate_many([vehicle])
        assert (one.state, one.warning) == (many.state, many.warning)
        assert single.memory("truck") == batch.memory("truck")
        levels.add(int(one.level))
        s += speed_kmh / 3.6 * 0.1
        speed_kmh = max(speed_kmh - (0.9 if one.level == 2 else 0.2), 40.0)
    assert levels == {0, 1, 2}


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    policy=_policies(),
    radii=st.lists(_radii, min_size=1, max_size=12),
    columns=st.lists(st.integers(0, len(Column) - 1), min_size=1, max_size=3),
)
def test_remembered_warning_speeds_are_the_tables_to_the_bit(monkeypatch, policy, radii, columns) -> None:
    """V_w of both levels as the settings remember them per radius and column is the array look-up's
    (Tables 1-2), on the first ask, the next, and after the memory started afresh."""
    monkeypatch.setattr("csws.warning.settings.WARNING_SPEEDS_REMEMBERED", 5)
    warning_settings = WarningSettings(policy=policy)
    for _ in range(2):
        for radius_m in radii:
            for column in columns:
                truth = policy.warning_speeds_kmh(np.array([radius_m]), np.array([column]))[:, 0].tolist()
                assert list(warning_settings.warning_speeds_one_kmh(radius_m, column)) == truth
