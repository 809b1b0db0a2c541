"""The update period learnt from each vehicle's timestamps, the fix's age, and the hold scaled with the period.

Truth is constructed here: a road of a straight and an arc built with netconvert, the vehicle's
positions from its constant speed, V_w from the standard's tables and formula (1) computed in the test.
"""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
import numpy as np
import pytest
from builders import edge_xml, node_xml

from csws.engine import Engine, EngineSettings, VehicleInput, VehicleMemory
from csws.geometry import arc, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.standard import warning_speed
from csws.sumo.netbuild import netconvert
from csws.warning.latency import KEPT_INTERVALS, MIN_INTERVALS, fix_age_s, next_intervals, update_period_s
from csws.warning.rules import WarningSettings
from service.sessions import Session, SessionRecord
from service.settings import ServiceSettings

#: The road: a straight, then an arc turning left, then a straight.
APPROACH_M = 800.0
RADIUS_M = 150.0
PIECES = (straight(APPROACH_M), arc(RADIUS_M, 60.0, "left"), straight(300.0))
#: How far the fitted curve start may lie from the constructed one, m.
START_TOLERANCE_M = 1.5
#: Formula (1)'s constants (6.1): 0.8 s reaction, g.
REACTION_S, G_MPS2 = 0.8, 9.8
SPEED_KMH = 90.0
CATEGORY = "N"


@pytest.fixture(scope="module")
def road(tmp_path_factory: pytest.TempPathFactory) -> tuple[RoadMap, str]:
    """The one-lane road and its lane."""
    xy, _ = sample_pieces(PIECES, 2.0, (0.0, 0.0), 0.0)
    nodes = node_xml("A", xy[0]) + node_xml("B", xy[-1])
    folder: Path = tmp_path_factory.mktemp("latency")
    net = netconvert(f"<nodes>{nodes}</nodes>", f"<edges>{edge_xml('r', 'A', 'B', xy)}</edges>", folder / "r.net.xml")
    road_map = RoadMap.load(net)
    lane = "r_0"
    [curve] = road_map.lane_curves(lane)
    assert abs(curve.start_pos_m - APPROACH_M) <= START_TOLERANCE_M  # the map sees the constructed curve
    return road_map, lane


def _formula_1_m(speed_kmh: float, warning_speed_kmh: float) -> float:
    """S_w of formula (1): 0.8 v + (v^2 - v_w^2) / g, m."""
    v, v_w = speed_kmh / 3.6, warning_speed_kmh / 3.6
    return REACTION_S * v + (v * v - v_w * v_w) / G_MPS2


def _onset_distance_m(
    road: tuple[RoadMap, str], settings: WarningSettings, period_s: float, phase_m: float, age_s: float
) -> float:
    """Drive at constant speed towards the curve, a fix every ``period_s`` each ``age_s`` old when answered;
    the distance to the constructed curve start at the first fix that gets level 1."""
    road_map, lane = road
    engine = Engine(road_map, EngineSettings(warning=settings))
    speed_mps = SPEED_KMH / 3.6
    for k in range(200):
        position_m = APPROACH_M - 600.0 + phase_m + speed_mps * period_s * k
        fix = VehicleInput("truck", CATEGORY, SPEED_KMH, lane, position_m, timestamp_s=k * period_s, age_s=age_s)
        if engine.evaluate(fix).level >= 1:
            return APPROACH_M - position_m
    raise AssertionError("level 1 never came on")


@pytest.mark.sumo
@pytest.mark.parametrize("age_s", [0.0, 0.4])
@pytest.mark.parametrize("period_s", [1.0, 2.0])
def test_a_vehicle_reporting_slowly_is_warned_before_formula_1s_point(road, period_s, age_s):
    """Learnt, not configured: the level shown at the fix before S_w is reached, whatever the phase of
    the fixes; and it comes on no earlier than the next fix would be too late."""
    v_w1 = warning_speed(RADIUS_M, CATEGORY, 1)
    sw_m = _formula_1_m(SPEED_KMH, v_w1)
    speed_mps = SPEED_KMH / 3.6
    settings = WarningSettings()  # configured period 0.1 s: the vehicle's own is learnt
    delay_s = settings.system_delay_s
    step_m = speed_mps * period_s
    for phase_m in np.linspace(0.0, step_m, 6, endpoint=False).tolist():
        onset_m = _onset_distance_m(road, settings, period_s, phase_m, age_s)
        # Where the vehicle is when the answer to that fix is shown: before S_w.
        assert onset_m - speed_mps * (age_s + delay_s) >= sw_m - START_TOLERANCE_M
        # No later than formula (1)'s point plus one interval of travel (the issue's bound), a fortiori.
        assert onset_m >= sw_m - step_m
        # And at the last fix that could: the next one would be answered inside S_w.
        assert onset_m <= sw_m + speed_mps * (period_s + age_s + delay_s) + START_TOLERANCE_M


@pytest.mark.sumo
def test_a_pinned_period_leaves_a_slow_vehicle_late(road):
    """The same drive with the period pinned to 0.1 s: some phase of 1 s fixes is warned inside S_w."""
    sw_m = _formula_1_m(SPEED_KMH, warning_speed(RADIUS_M, CATEGORY, 1))
    speed_mps = SPEED_KMH / 3.6
    pinned = WarningSettings(learn_update_period=False)
    shown_at_m = [
        _onset_distance_m(road, pinned, 1.0, phase_m, 0.0) - speed_mps * pinned.system_delay_s
        for phase_m in np.linspace(0.0, speed_mps, 6, endpoint=False).tolist()
    ]
    assert min(shown_at_m) < sw_m - speed_mps * 0.5


def _learn(timestamps_s, settings: WarningSettings = WarningSettings()) -> list[float]:
    """The update period after each of a vehicle's timestamps, every fix accepted."""
    intervals: tuple[float, ...] = ()
    last = None
    periods = []
    for timestamp_s in timestamps_s:
        intervals = next_intervals(intervals, last, timestamp_s)
        last = timestamp_s
        periods.append(update_period_s(intervals, settings))
    return periods


def test_the_configured_period_holds_until_enough_intervals_are_seen():
    periods = _learn([0.0, 1.0, 2.0, 3.0, 4.0])
    configured = WarningSettings().update_period_s
    assert periods[:MIN_INTERVALS] == [configured] * MIN_INTERVALS
    assert periods[MIN_INTERVALS:] == [1.0, 1.0]


def test_the_learnt_period_is_the_median_and_ignores_one_long_gap():
    timestamps = [0.0, 1.0, 2.0, 3.0, 4.0, 14.0, 15.0, 16.0]  # a 10 s gap: a tunnel
    assert _learn(timestamps)[-4:] == [1.0, 1.0, 1.0, 1.0]
    # A fleet that changes its rate from 1 s to 0.2 s is followed once most recent intervals say so.
    faster = [*timestamps, 16.2, 16.4, 16.6]
    periods = _learn(faster)
    assert periods[-1] == pytest.approx(0.2)
    assert len(next_intervals((1.0,) * KEPT_INTERVALS, 0.0, 0.2)) == KEPT_INTERVALS


def test_the_learnt_period_is_capped_and_can_be_pinned():
    assert _learn([0.0, 10.0, 20.0, 30.0])[-1] == WarningSettings().max_update_period_s
    pinned = WarningSettings(update_period_s=0.5, learn_update_period=False)
    assert _learn([0.0, 1.0, 2.0, 3.0, 4.0], pinned)[-1] == 0.5


def test_repeated_or_earlier_timestamps_add_no_interval():
    assert next_intervals((1.0,), 5.0, 5.0) == (1.0,)  # the same fix sent twice
    assert next_intervals((1.0,), 5.0, 2.0) == (1.0,)  # the clock started again
    assert next_intervals((1.0,), None, 2.0) == (1.0,)
    assert fix_age_s(-0.3) == 0.0 and fix_age_s(None) == 0.0 and fix_age_s(0.7) == 0.7


@pytest.mark.sumo
def test_the_engine_keeps_the_intervals_in_the_vehicles_memory(road):
    """Learnt in one engine, taken up by another from the memory (as the service's workers do), through MessagePack."""
    road_map, lane = road
    first, second = Engine(road_map), Engine(road_map)
    for k in range(5):
        first.evaluate(VehicleInput("bus", "M3", 50.0, lane, 10.0 + 14.0 * k, timestamp_s=100.0 + k))
    memory = first.memory("bus")
    assert first.update_period_s("bus") == 1.0 and len(memory.intervals_s) == 4
    encoded = msgspec.msgpack.encode(memory)
    second.restore("bus", msgspec.msgpack.decode(encoded, type=VehicleMemory))
    assert second.update_period_s("bus") == 1.0
    [answer] = second.evaluate_many([VehicleInput("bus", "M3", 50.0, lane, 80.0, timestamp_s=105.0)])
    assert answer.state == "active" and len(second.memory("bus").intervals_s) == KEPT_INTERVALS
    second.forget("bus")
    assert second.update_period_s("bus") == WarningSettings().update_period_s


def _levels_with_one_noisy_fix(road, settings: WarningSettings, batch: bool) -> list[int]:
    """Levels of a vehicle fixed every 1 s inside its warning area, one fix 60 m
    behind where it is (beyond the allowance)."""
    road_map, lane = road
    engine = Engine(road_map, EngineSettings(warning=settings))
    speed_mps = SPEED_KMH / 3.6
    sw_m = _formula_1_m(SPEED_KMH, warning_speed(RADIUS_M, CATEGORY, 1))
    start_m = APPROACH_M - sw_m - 8 * speed_mps  # level 1 is due from the 8th fix on
    levels = []
    for k in range(11):
        position_m = start_m + speed_mps * k - (60.0 if k == 9 else 0.0)
        fix = VehicleInput("truck", CATEGORY, SPEED_KMH, lane, position_m, timestamp_s=float(k))
        answer = engine.evaluate_many([fix])[0] if batch else engine.evaluate(fix)
        levels.append(int(answer.level))
    return levels


@pytest.mark.sumo
@pytest.mark.parametrize("batch", [False, True])
def test_one_noisy_fix_between_1_s_fixes_does_not_switch_the_warning_off_and_on(road, batch):
    levels = _levels_with_one_noisy_fix(road, WarningSettings(), batch)
    assert levels[:7] == [0] * 7 and min(levels[8:]) >= 1
    # With the hold of 1 s and no period learnt, the same fix switches it off and on again.
    pinned = _levels_with_one_noisy_fix(road, WarningSettings(learn_update_period=False), batch)
    assert pinned[8] >= 1 and pinned[9] == 0 and pinned[10] >= 1


@pytest.mark.sumo
def test_the_service_settings_pin_the_release_rule(road, monkeypatch):
    """CSWS_RELEASE_HOLD_S and CSWS_RELEASE_HOLD_INTERVALS at 0 turn the hold off: the noisy fix then switches the
    warning off and on again, as the service's engine is set."""
    monkeypatch.setenv("CSWS_RELEASE_HOLD_S", "0")
    monkeypatch.setenv("CSWS_RELEASE_HOLD_INTERVALS", "0")
    monkeypatch.setenv("CSWS_RELEASE_MARGIN_KMH", "2.5")
    warning = ServiceSettings().engine_settings().warning
    assert (warning.release_hold_s, warning.release_hold_intervals, warning.release_margin_kmh) == (0.0, 0.0, 2.5)
    levels = _levels_with_one_noisy_fix(road, warning, batch=True)
    assert levels[8] >= 1 and levels[9] == 0 and levels[10] >= 1


def test_the_hold_lasts_at_least_one_and_a_half_periods():
    settings = WarningSettings()
    assert settings.hold_s(0.1) == settings.release_hold_s
    assert settings.hold_s(2.0) == 3.0
    assert np.array_equal(settings.hold_s(np.array([0.1, 2.0])), [settings.release_hold_s, 3.0])
    assert math.isclose(settings.allowance_m(10.0, 1.0, 0.5), 10.0 * (1.0 + settings.system_delay_s + 0.5))


def test_the_service_session_keeps_the_intervals():
    """A session written to the store and read back gives the engine the same intervals."""
    memory = VehicleMemory(intervals_s=(1.0, 1.0, 0.98, 1.02))
    record = SessionRecord.of("net", Session(0, "r_0", 12.5), memory)
    decoded = msgspec.msgpack.decode(msgspec.msgpack.encode(record), type=SessionRecord)
    assert decoded.memory() == memory


@pytest.mark.sumo
def test_the_engine_learns_the_median_through_a_gap_and_not_from_faults(road):
    """Fixes every 1 s, a 10 s gap, and fixes that match no lane between: the period stays 1 s."""
    road_map, lane = road
    engine = Engine(road_map)
    for timestamp_s in (0.0, 1.0, 2.0, 3.0, 13.0, 14.0):
        engine.evaluate(VehicleInput("van", "N", 50.0, lane, 10.0 + 14.0 * timestamp_s, timestamp_s=timestamp_s))
        if timestamp_s == 13.0:
            engine.evaluate(VehicleInput("van", "N", 50.0, None, timestamp_s=13.5))  # a fault: no interval
    assert engine.memory("van").intervals_s == (1.0, 1.0, 1.0, 10.0, 1.0)
    assert engine.update_period_s("van") == 1.0
