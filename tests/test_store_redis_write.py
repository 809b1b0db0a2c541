"""The Redis store's write, its vehicles packed into one value: every field arrives whole, as on SQLite.

Random writes (any bytes in a session, keys in any script, places on networks whose names hold ``|``,
settings or none, places or none) go to a real ``redis-server`` and to a SQLite store; each store must read
back exactly what was written, with the next version, and the raw keys of Redis must hold the stored format
the reads of older code take (``{version}|{session}``, the setting's switch and category). A write at a stale
version is refused for that vehicle alone, a session written by older code is read (with its last event's number)
and written over, and a vehicle the store holds nothing of is read as nothing.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
import redis
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csws.standard import Category
from service.store import Place, StoredVehicle, VehicleSetting, VehicleWrite
from service.store.redis import EVENT_SEQ_PREFIX, PLACES_KEY, SESSION_PREFIX, SETTING_PREFIX, RedisStore
from service.store.sqlite import SQLiteStore

IDLE_S = 600.0
#: Each example's vehicles get keys of their own (the database is not emptied between examples).
_EXAMPLES = itertools.count()

_settings = st.one_of(
    st.none(), st.builds(VehicleSetting, st.booleans(), st.one_of(st.none(), st.sampled_from(Category)))
)
_places = st.one_of(
    st.none(),
    st.builds(Place, st.sampled_from(["town", "ring|west", "é|x|y"]), st.floats(-180, 180), st.floats(-85, 85)),
)
_vehicle = st.tuples(
    st.text(st.characters(blacklist_categories=("Cc", "Cs")), min_size=1, max_size=12).filter(lambda t: "/" not in t),
    st.binary(max_size=300),
    _settings,
    _places,
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(vehicles=st.lists(_vehicle, min_size=1, max_size=12, unique_by=lambda v: v[0]))
def test_every_field_of_a_packed_write_is_read_back_as_sqlite_reads_it(
    redis_url: str, tmp_path: Path, vehicles: list[tuple[str, bytes, VehicleSetting | None, Place | None]]
) -> None:
    example = next(_EXAMPLES)
    keys = [f"fleet{example}/{name}" for name, *_ in vehicles]
    writes = {
        key: VehicleWrite(0, session, setting, place)
        for key, (_, session, setting, place) in zip(keys, vehicles, strict=True)
    }
    store = RedisStore(redis_url, IDLE_S)
    sqlite_store = SQLiteStore(tmp_path / f"vehicles{example}.sqlite3", IDLE_S)
    try:
        assert store.write(writes) == set() and sqlite_store.write(writes) == set()
        read, sqlite_read = store.read(keys), sqlite_store.read(keys)
        client = redis.Redis.from_url(redis_url)
        for key, w in writes.items():
            assert read[key].session == w.session and read[key].version == 1
            assert read[key].setting == w.setting and sqlite_read[key][:3] == read[key][:3]
            assert client.get(SESSION_PREFIX + key) == b"1|" + w.session
            if w.setting is not None:
                category = w.setting.category.value if w.setting.category is not None else ""
                assert (
                    client.get(SETTING_PREFIX + key)
                    == ("1" if w.setting.switched_on else "0").encode() + category.encode()
                )
            if w.place is not None:
                assert client.hget(PLACES_KEY, key) == f"{w.place.network}|{w.place.x!r}|{w.place.y!r}".encode()
        client.close()
    finally:
        store.close()
        sqlite_store.close()


def test_a_stale_version_is_refused_for_its_vehicle_alone_and_an_older_session_is_taken_up(redis_url: str) -> None:
    store = RedisStore(redis_url, IDLE_S)
    client = redis.Redis.from_url(redis_url)
    try:
        client.set(SESSION_PREFIX + "f/old", b"7|\x93written|before")  # as older code stored it
        client.set(EVENT_SEQ_PREFIX + "f/old", b"41")
        read = store.read(["f/old", "f/never"])
        assert read["f/old"] == StoredVehicle(None, b"\x93written|before", 7, 41)
        assert read["f/never"] == StoredVehicle()
        first = {"f/a": VehicleWrite(0, b"a1"), "f/b": VehicleWrite(0, b"b1")}
        assert store.write(first) == set()
        again = {"f/a": VehicleWrite(0, b"a2"), "f/b": VehicleWrite(1, b"b2"), "f/old": VehicleWrite(7, b"o8")}
        assert store.write(again) == {"f/a"}
        read = store.read(["f/a", "f/b", "f/old"])
        assert (read["f/a"].session, read["f/a"].version) == (b"a1", 1)
        assert (read["f/b"].session, read["f/b"].version) == (b"b2", 2)
        assert (read["f/old"].session, read["f/old"].version) == (b"o8", 8)
    finally:
        client.close()
        store.close()


@pytest.mark.parametrize("count", [1, 300])
def test_a_write_of_many_vehicles_keeps_each_vehicles_fields_apart(redis_url: str, count: int) -> None:
    store = RedisStore(redis_url, IDLE_S)
    try:
        writes = {
            f"f/v{i}": VehicleWrite(0, bytes([i % 256]) * (i % 7), None, Place("n", float(i), -i / 3))
            for i in range(count)
        }
        assert store.write(writes) == set()
        read = store.read(list(writes))
        assert all(read[key].session == w.session and read[key].version == 1 for key, w in writes.items())
    finally:
        store.close()
