"""The fleet's forward collision warning (numpy columns) against the vehicle's (plain floats): the same
answers to the bit, frame after frame, on random fleets, objects and map paths; and its bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from csws.fcw.fleet import UNKNOWN_LANE, FleetEgo, FleetMemory, FleetObjects, FleetPaths, update_fleet
from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.path import PathCurvature
from csws.fcw.settings import FcwSettings
from csws.fcw.state import FCW_STATES
from csws.fcw.tracker import ForwardCollisionWarning

FINITE = {"allow_nan": False, "allow_infinity": False}
MOSTLY_TRUE = st.sampled_from([True] * 5 + [False])
OBJECT = st.fixed_dictionaries(
    {
        "id": st.integers(0, 6),
        "x_m": st.floats(-5.0, 120.0, **FINITE),
        "y_m": st.floats(-4.0, 4.0, **FINITE),
        "relative_speed_mps": st.floats(-30.0, 5.0, **FINITE),
        "accel_mps2": st.floats(-9.0, 4.0, **FINITE),
        "accel_is_relative": st.booleans(),
        "lane": st.none() | st.integers(-1, 1),
    }
)
EGO = st.fixed_dictionaries(
    {
        "speed_mps": st.floats(0.0, 45.0, **FINITE),
        "accel_mps2": st.floats(-7.0, 3.0, **FINITE),
        "yaw_rate_rps": st.none() | st.floats(-0.3, 0.3, **FINITE),
        "curvature_1pm": st.none() | st.floats(-0.01, 0.01, **FINITE),
        "braking": st.booleans(),
        "turn_signal": st.integers(-1, 1),
        "switched_on": MOSTLY_TRUE,
        "forward_gear": MOSTLY_TRUE,
        "sensor_ok": MOSTLY_TRUE,
    }
)
PATH = st.none() | st.lists(
    st.tuples(st.floats(1.0, 60.0, **FINITE), st.floats(-0.012, 0.012, **FINITE)), min_size=0, max_size=6
).map(
    lambda knots: PathCurvature(
        tuple(np.concatenate(([0.0], np.cumsum([h for h, _ in knots]))).tolist()),
        (0.004, *(k for _, k in knots)),
    )
)


def _unique(objects: list[dict]) -> list[dict]:
    seen: dict[int, dict] = {}
    for obj in objects:
        seen.setdefault(obj["id"], obj)
    return list(seen.values())


def _fleet_frame(settings_, memory, time_s, egos, object_lists, paths):
    ego = FleetEgo.of(
        [e["speed_mps"] for e in egos],
        [e["accel_mps2"] for e in egos],
        [math.nan if e["yaw_rate_rps"] is None else e["yaw_rate_rps"] for e in egos],
        [math.nan if e["curvature_1pm"] is None else e["curvature_1pm"] for e in egos],
        *([e[name] for e in egos] for name in ("braking", "turn_signal", "switched_on", "forward_gear", "sensor_ok")),
    )
    flat = [(v, o) for v, objects in enumerate(object_lists) for o in objects]
    objects = FleetObjects.of(
        [v for v, _ in flat],
        [o["id"] for _, o in flat],
        [o["x_m"] for _, o in flat],
        [o["y_m"] for _, o in flat],
        [o["relative_speed_mps"] for _, o in flat],
        [o["accel_mps2"] for _, o in flat],
        [o["accel_is_relative"] for _, o in flat],
        1.8,
        [UNKNOWN_LANE if o["lane"] is None else o["lane"] for _, o in flat],
    )
    knots = [
        (v, s, k) for v, path in enumerate(paths) if path for s, k in zip(path.s_m, path.curvature_1pm, strict=True)
    ]
    fleet_paths = FleetPaths(*(np.array(column) for column in zip(*knots, strict=True))) if knots else None
    return update_fleet(settings_, memory, time_s, ego, objects, fleet_paths)


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


@settings(deadline=None, max_examples=300)
@given(
    st.integers(1, 4).flatmap(
        lambda n: st.tuples(
            st.lists(PATH, min_size=n, max_size=n),
            st.lists(
                st.tuples(
                    st.lists(EGO, min_size=n, max_size=n),
                    st.lists(st.lists(OBJECT, max_size=5), min_size=n, max_size=n),
                ),
                min_size=1,
                max_size=4,
            ),
        )
    )
)
def test_the_fleet_gives_each_vehicle_the_answers_of_its_own_system_to_the_bit(fleet):
    paths, frames = fleet
    settings_ = FcwSettings(min_speed_mps=2.0)
    systems = [ForwardCollisionWarning(settings_) for _ in paths]
    memory = FleetMemory.new(len(paths))
    for k, (egos, object_lists) in enumerate(frames):
        object_lists = [_unique(objects) for objects in object_lists]
        time_s = 0.1 * k
        batch, memory = _fleet_frame(settings_, memory, time_s, egos, object_lists, paths)
        for v, system in enumerate(systems):
            ego = EgoMotion(**egos[v], map_path=paths[v])
            one = system.update(time_s, ego, [SensorObject(**o) for o in object_lists[v]])
            event(f"level {one.level}, map {paths[v] is not None}, target {one.target_id is not None}")
            assert one.state == FCW_STATES[batch.state[v]]
            assert (one.level, one.required_level) == (batch.level[v], batch.required_level[v])
            assert (one.target_id if one.target_id is not None else -1) == batch.target_id[v]
            for name in ("clearance_m", "relative_speed_mps", "ttc_s", "ettc_s", "a_req_mps2", "path_offset_m"):
                assert _same(getattr(one, name), float(getattr(batch, name)[v])), name


def test_bad_fleet_columns_raise_naming_them():
    with pytest.raises(ValueError, match="objects x_m"):
        FleetObjects.of([0], [1], [math.nan], [0.0], [0.0])
    with pytest.raises(ValueError, match="ego speed_mps"):
        FleetEgo.of([math.nan])
    objects = FleetObjects.of([0, 0], [5, 5], [10.0, 20.0], [0.0, 0.0], [-1.0, -1.0])
    with pytest.raises(ValueError, match="duplicate object ids"):
        update_fleet(FcwSettings(), FleetMemory.new(1), 0.0, FleetEgo.of([20.0]), objects)
    objects = FleetObjects.of([1], [5], [10.0], [0.0], [-1.0])
    with pytest.raises(ValueError, match="objects vehicle"):
        update_fleet(FcwSettings(), FleetMemory.new(1), 0.0, FleetEgo.of([20.0]), objects)


CROWDED_OBJECT = st.fixed_dictionaries(
    {
        "id": st.integers(0, 30),
        # few distinct values, so that objects tie on clearance, speed and a_req and the ranking's order decides
        "x_m": st.sampled_from([0.0, 8.0, 25.0, 60.0]) | st.floats(0.0, 150.0, allow_nan=False, allow_infinity=False),
        "y_m": st.floats(-1.5, 1.5, allow_nan=False, allow_infinity=False),
        "relative_speed_mps": st.sampled_from([-20.0, -8.0, 0.0, 1.0])
        | st.floats(-30.0, 5.0, allow_nan=False, allow_infinity=False),
        "accel_mps2": st.sampled_from([0.0, -3.0, -9.0]) | st.floats(-9.0, 4.0, allow_nan=False, allow_infinity=False),
        "accel_is_relative": st.booleans(),
        "lane": st.none() | st.just(0),
    }
)


@settings(deadline=None, max_examples=200)
@given(
    st.lists(
        st.tuples(EGO, st.lists(CROWDED_OBJECT, min_size=2, max_size=10)),
        min_size=1,
        max_size=5,
    ),
    PATH,
)
def test_with_many_objects_in_the_path_the_vehicle_chooses_the_fleets_target_with_its_figures(frames, path):
    """Up to 10 objects in the path at once, often tied: the single vehicle's ranking (which assesses only
    what a choice needs) picks the fleet's target (which assesses every object) with the same figures."""
    settings_ = FcwSettings(min_speed_mps=2.0)
    system, memory = ForwardCollisionWarning(settings_), FleetMemory.new(1)
    for k, (ego_values, objects) in enumerate(frames):
        objects = _unique(objects)
        batch, memory = _fleet_frame(settings_, memory, 0.1 * k, [ego_values], [objects], [path])
        one = system.update(0.1 * k, EgoMotion(**ego_values, map_path=path), [SensorObject(**o) for o in objects])
        event(f"level {one.level}, target {one.target_id is not None}")
        assert (one.level, one.required_level) == (batch.level[0], batch.required_level[0])
        assert (one.target_id if one.target_id is not None else -1) == batch.target_id[0]
        for name in ("clearance_m", "relative_speed_mps", "ttc_s", "ettc_s", "a_req_mps2", "path_offset_m"):
            assert _same(getattr(one, name), float(getattr(batch, name)[0])), name
