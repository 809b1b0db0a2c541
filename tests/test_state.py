"""The per-vehicle system state of clauses 5.2-5.4."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.state import (
    ACTIVATION_ON_START_KMH,
    STALE_AFTER_S,
    ActivationSettings,
    Fault,
    SystemState,
    VehicleStatus,
    next_status,
    switch,
)

SPEED_ACTIVATION = ActivationSettings(activation_speed_kmh=30.0, hysteresis_kmh=5.0, stale_after_s=2.0)


def test_activation_on_start_is_the_default():
    status = next_status(VehicleStatus(), 0.0)
    assert status.state is SystemState.ACTIVE and status.warns


def test_speed_activation_with_hysteresis_does_not_flicker():
    states = []
    status = VehicleStatus()
    for speed_kmh in (10, 29.9, 30, 28, 26, 25.1, 24.9, 27, 29.9, 30):
        status = next_status(status, speed_kmh, settings=SPEED_ACTIVATION)
        states.append(status.state)
    A, S = SystemState.ACTIVE, SystemState.STANDBY
    assert states == [S, S, A, A, A, A, S, S, S, A]


def test_the_driver_switches_it_off_and_on():
    status = next_status(VehicleStatus(), 80.0)
    off = switch(status, on=False)
    assert off.state is SystemState.OFF and not off.warns
    assert next_status(off, 80.0).state is SystemState.OFF  # stays off whatever the vehicle does
    on = switch(off, on=True)
    assert on.state is SystemState.STANDBY
    assert next_status(on, 80.0).state is SystemState.ACTIVE


@pytest.mark.parametrize(
    "kwargs, fault",
    [
        (dict(speed_kmh=math.nan), Fault.INVALID_INPUT),
        (dict(speed_kmh=-5.0), Fault.INVALID_INPUT),
        (dict(speed_kmh=50.0, age_s=5.0), Fault.STALE_INPUT),
        (dict(speed_kmh=50.0, found_fault=Fault.NO_MAP_MATCH), Fault.NO_MAP_MATCH),
        (dict(speed_kmh=50.0, found_fault=Fault.NO_MAP), Fault.NO_MAP),
    ],
)
def test_faults_turn_warnings_off_with_a_reason_and_clear_on_good_input(kwargs, fault):
    active = next_status(VehicleStatus(), 50.0, timestamp_s=10.0)
    faulty = next_status(active, settings=ActivationSettings(), **kwargs)
    assert faulty.state is SystemState.FAULT and faulty.fault is fault and not faulty.warns
    recovered = next_status(faulty, 50.0, timestamp_s=11.0)
    assert recovered.state is SystemState.ACTIVE and recovered.fault is None


def test_an_update_older_than_the_last_one_is_stale():
    status = next_status(VehicleStatus(), 50.0, timestamp_s=10.0)
    assert next_status(status, 50.0, timestamp_s=9.5).fault is Fault.STALE_INPUT
    assert next_status(status, 50.0, timestamp_s=10.5).state is SystemState.ACTIVE


def test_one_fix_from_far_in_the_future_silences_no_fix_after_it():
    status = next_status(VehicleStatus(), 50.0, timestamp_s=1_700_000_000.0)
    bad = next_status(status, 50.0, timestamp_s=1e308)  # one fix with a wild timestamp
    after = next_status(bad, 50.0, timestamp_s=1_700_000_000.1)
    assert after.state is SystemState.ACTIVE and after.fault is None
    assert next_status(after, 50.0, timestamp_s=1_700_000_000.2).state is SystemState.ACTIVE


def test_a_clock_that_starts_again_is_accepted_and_a_late_fix_is_still_stale():
    settings = ActivationSettings()
    status = next_status(VehicleStatus(), 50.0, timestamp_s=5000.0)
    restarted = next_status(status, 50.0, timestamp_s=5000.0 - settings.clock_jump_s - 1.0)
    assert restarted.state is SystemState.ACTIVE and restarted.last_timestamp_s == 5000.0 - settings.clock_jump_s - 1.0
    late = next_status(status, 50.0, timestamp_s=5000.0 - settings.clock_jump_s + 1.0)
    assert late.fault is Fault.STALE_INPUT and late.last_timestamp_s == 5000.0


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="activation_speed_kmh must be a non-negative number"):
        ActivationSettings(activation_speed_kmh=-1.0)


@settings(max_examples=200, deadline=None)
@given(speeds=st.lists(st.floats(0.0, 120.0), min_size=1, max_size=40))
def test_never_active_below_the_release_speed_and_always_above_the_activation_speed(speeds):
    status = VehicleStatus()
    for speed_kmh in speeds:
        status = next_status(status, speed_kmh, settings=SPEED_ACTIVATION)
        if speed_kmh < SPEED_ACTIVATION.activation_speed_kmh - SPEED_ACTIVATION.hysteresis_kmh:
            assert status.state is SystemState.STANDBY
        if speed_kmh >= SPEED_ACTIVATION.activation_speed_kmh:
            assert status.state is SystemState.ACTIVE


def test_speed_0_is_active_on_start_and_standby_with_speed_activation():
    """5.3.2 a) (the default): activated with the vehicle's start, at any speed; 5.3.2 b): a vehicle standing still
    has not reached the activation speed, and one that stops falls back to standby below it less the hysteresis."""
    assert ActivationSettings().activation_speed_kmh == ACTIVATION_ON_START_KMH == 0.0
    assert next_status(VehicleStatus(), 0.0).state is SystemState.ACTIVE
    assert next_status(VehicleStatus(), 0.0, settings=SPEED_ACTIVATION).state is SystemState.STANDBY
    moving = next_status(VehicleStatus(), 50.0, settings=SPEED_ACTIVATION)
    assert next_status(moving, 0.0, settings=SPEED_ACTIVATION).state is SystemState.STANDBY


def test_fault_codes_are_stable():
    assert {fault: fault.code for fault in Fault} == {
        Fault.NO_MAP: "no_map",
        Fault.NO_MAP_MATCH: "no_map_match",
        Fault.STALE_INPUT: "stale_input",
        Fault.INVALID_INPUT: "invalid_input",
    }


@pytest.mark.parametrize("age_s, stale", [(STALE_AFTER_S, False), (STALE_AFTER_S + 0.01, True)])
def test_a_fix_older_than_the_staleness_limit_is_stale(age_s, stale):
    status = next_status(VehicleStatus(), 50.0, age_s=age_s)
    assert (status.fault is Fault.STALE_INPUT) is stale and STALE_AFTER_S == ActivationSettings().stale_after_s
