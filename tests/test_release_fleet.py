"""The release rule's fleet steps give each vehicle what its own memory and CPOIs say, whatever the fleet."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.warning.release import NOT_HELD, HeldWarning, Rule, memory_masks, next_memories, rows_of_vehicles

_keys = st.tuples(st.sampled_from(["a@0", "b@120", "c@7"]), st.integers(0, 3))
_times = st.one_of(st.none(), st.floats(min_value=0.0, max_value=5.0), st.sampled_from([math.nan, math.inf]))
_memories = st.one_of(
    st.just(NOT_HELD),
    st.builds(
        HeldWarning,
        points=st.tuples(st.frozensets(_keys, max_size=4), st.frozensets(_keys, max_size=4)),
        kept_at_s=st.tuples(_times, _times),
    ),
)
#: One vehicle: its memory, this update's timestamp, its CPOIs (keys, unique) and their rule codes.
_vehicles = st.tuples(
    _memories,
    _times,
    st.lists(st.tuples(_keys, st.integers(0, 3), st.integers(0, 3)), max_size=6, unique_by=lambda cpoi: cpoi[0]),
)


def _flat(vehicles):
    """The vehicles' CPOIs as the flat columns the fleet steps read, with each vehicle's first row."""
    sizes = [len(cpois) for _, _, cpois in vehicles]
    first = [0, *np.cumsum(sizes).tolist()]
    cpois = [cpoi for _, _, vehicle_cpois in vehicles for cpoi in vehicle_cpois]
    curve_ids = [key[0] for key, _, _ in cpois]
    parts = [key[1] for key, _, _ in cpois]
    rules = np.array([[rule_1 for _, rule_1, _ in cpois], [rule_2 for _, _, rule_2 in cpois]], dtype=np.int8)
    return first, curve_ids, parts, rules.reshape(2, len(cpois))


@settings(max_examples=300, deadline=None)
@given(st.lists(_vehicles, max_size=8), st.floats(min_value=0.1, max_value=3.0), st.data())
def test_memory_masks_name_each_vehicles_remembered_cpois(vehicles, hold_s, data):
    first, curve_ids, parts, _ = _flat(vehicles)
    recalled = data.draw(st.lists(st.booleans(), min_size=len(curve_ids), max_size=len(curve_ids)))
    held = [memory for memory, _, _ in vehicles]
    now_s = [now for _, now, _ in vehicles]
    latched, hold = memory_masks(held, now_s, first, curve_ids, parts, hold_s, np.array(recalled, dtype=bool))
    for vehicle, (memory, now, cpois) in enumerate(vehicles):
        for offset, (key, _, _) in enumerate(cpois):
            row = first[vehicle] + offset
            for level in (0, 1):
                named = key in memory.points[level]
                kept = memory.kept_at_s[level]
                within = kept is not None and now is not None and math.isfinite(now) and now - kept < hold_s
                assert latched[level, row] == (named and not recalled[row])
                assert hold[level, row] == (named and within)


@settings(max_examples=300, deadline=None)
@given(st.lists(_vehicles, max_size=8), st.data())
def test_next_memories_keep_what_kept_each_level_on(vehicles, data):
    first, curve_ids, parts, rules = _flat(vehicles)
    distances = data.draw(st.lists(st.floats(0.0, 500.0), min_size=len(curve_ids), max_size=len(curve_ids)))
    radii = data.draw(st.lists(st.floats(5.0, 3000.0), min_size=len(curve_ids), max_size=len(curve_ids)))
    speeds = data.draw(st.lists(st.floats(0.0, 150.0), min_size=len(vehicles), max_size=len(vehicles)))
    held = [memory for memory, _, _ in vehicles]
    now_s = [now for _, now, _ in vehicles]
    places = (np.array(distances), np.array(radii), np.array(speeds))
    memories = next_memories(held, now_s, first, curve_ids, parts, rules, places)
    for vehicle, (before, now, cpois) in enumerate(vehicles):
        memory = memories[vehicle]
        if not any(rule_1 or rule_2 for _, rule_1, rule_2 in cpois):
            assert memory is NOT_HELD
            continue
        for level in (0, 1):
            codes = [cpoi[1 + level] for cpoi in cpois]
            assert memory.points[level] == {key for (key, _, _), code in zip(cpois, codes, strict=True) if code}
            if Rule.REQUIRED in codes or Rule.MARGIN in codes:
                assert memory.kept_at_s[level] is now
            elif Rule.HOLD in codes:
                assert memory.kept_at_s[level] is before.kept_at_s[level]
            else:
                assert memory.kept_at_s[level] is None
        rows = range(first[vehicle], first[vehicle + 1])
        if now is None or not math.isfinite(now):
            assert memory.places == () and memory.seen is None
            continue
        expected = tuple(
            (curve_ids[row], parts[row], distances[row], radii[row]) for row in rows if rules[0, row] or rules[1, row]
        )
        assert memory.places == expected
        assert memory.seen == (now, speeds[vehicle])


@given(st.lists(st.integers(0, 5), max_size=10), st.data())
def test_rows_of_vehicles_are_their_cpois_in_order(sizes, data):
    first = [0, *np.cumsum(sizes).tolist()]
    vehicles = data.draw(st.lists(st.integers(0, max(len(sizes) - 1, 0)), unique=True)) if sizes else []
    vehicles.sort()
    rows, owner = rows_of_vehicles(first, vehicles)
    expected = [
        (row, place) for place, vehicle in enumerate(vehicles) for row in range(first[vehicle], first[vehicle + 1])
    ]
    assert list(zip(rows.tolist(), owner.tolist(), strict=True)) == expected
