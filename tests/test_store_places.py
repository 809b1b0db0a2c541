"""The places of the fleet in both state stores: the Redis store's spatial index answers what SQLite's R*Tree does.

Random fleets (lon/lat and network metres, on two networks, in two fleets) are written to a SQLite
store and to a real ``redis-server``; some vehicles move (across the map, or to the other network),
some sessions expire. Every page asked of both (prefix, cursor, limit, networks, box or none) must be
the same, read from the index and along the keys alike, and the whole walk page after page must list
exactly the live vehicles the test itself finds in the box.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import pytest
import redis
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import service.store.redis as redis_store
from service.store import Box, Place, StateStore, VehicleWrite
from service.store.redis import (
    GRID_BUILT_KEY,
    GRID_PREFIX,
    PLACED_KEY,
    PLACES_KEY,
    RedisStore,
    axis_ordinal,
    box_ranges,
    place_cell,
)
from service.store.sqlite import SQLiteStore

IDLE_S = 60.0
NETWORKS = ("town", "ring|west")
FLEETS = ("alpha", "beta")
#: Coordinates of each kind: lon/lat (degrees) and network metres, both about zero and far from it.
KINDS = {"lonlat": ((-180.0, 180.0), (-85.0, 85.0)), "metres": ((-3000.0, 60000.0), (-3000.0, 60000.0))}


class Vehicle(NamedTuple):
    """One vehicle of a random fleet: its key, first place, place after its move (if it moves), whether it expires."""

    key: str
    first: Place
    moved: Place | None
    expires: bool

    @property
    def place(self) -> Place:
        return self.moved or self.first


def _coordinate(bounds: tuple[float, float]) -> st.SearchStrategy[float]:
    """Coordinates within bounds, often near a few spots (so that boxes catch several) and near zero (none
    nearer than 1e-30 but zero itself: the R*Tree keeps single precision, where they would be zero)."""
    spot = st.sampled_from([0.0, bounds[0] / 3.0, bounds[1] / 2.0])
    near = st.builds(lambda s, d: s + d, spot, st.floats(-2.0, 2.0))
    coordinates = st.one_of(near, st.floats(*bounds), st.floats(-1e-3, 1e-3))
    return coordinates.map(lambda v: v if abs(v) > 1e-30 else 0.0)


@st.composite
def fleets(draw: st.DrawFn) -> tuple[str, list[Vehicle]]:
    """A kind of coordinates and vehicles placed in them."""
    kind = draw(st.sampled_from(sorted(KINDS)))
    x_bounds, y_bounds = KINDS[kind]
    places = st.builds(Place, st.sampled_from(NETWORKS), _coordinate(x_bounds), _coordinate(y_bounds))
    names = draw(st.lists(st.text("abé/|0", min_size=1, max_size=4), min_size=1, max_size=30, unique=True))
    vehicles = [
        Vehicle(f"{draw(st.sampled_from(FLEETS))}/{name}", draw(places), draw(st.none() | places), draw(st.booleans()))
        for name in names
    ]
    return kind, vehicles


def _boxes(kind: str, vehicles: list[Vehicle]) -> st.SearchStrategy[Box]:
    """Boxes anywhere, and boxes about a vehicle's first or last place (edges from a centimetre to 100 km away)."""
    x_bounds, y_bounds = KINDS[kind]
    corner = st.tuples(_coordinate(x_bounds), _coordinate(y_bounds))
    reach = st.floats(0.0, 5.0) | st.floats(0.0, 1e5)
    anywhere = st.builds(lambda c, w, h: (c[0], c[1], c[0] + w, c[1] + h), corner, reach, reach)
    centres = st.sampled_from([p for v in vehicles for p in (v.first, v.place)])
    about = st.builds(lambda c, w, s, e, n: (c.x - w, c.y - s, c.x + e, c.y + n), centres, reach, reach, reach, reach)
    return anywhere | about


def _write_all(store: StateStore, vehicles: list[Vehicle]) -> None:
    """Each vehicle's first session and place, then each move as its second session."""
    store.write({v.key: VehicleWrite(0, v.key.encode(), place=v.first) for v in vehicles})
    moves = {v.key: VehicleWrite(1, v.key.encode() + b"+", place=v.moved) for v in vehicles if v.moved}
    assert store.write(moves) == set()


def _stores(redis_url: str, vehicles: list[Vehicle]) -> tuple[SQLiteStore, RedisStore]:
    """Both stores holding the fleet, the sessions of the vehicles that expire gone in each."""
    now_s = [0.0]
    sqlite_store = SQLiteStore(":memory:", IDLE_S, lambda: now_s[0])
    _write_all(sqlite_store, [v for v in vehicles if v.expires])
    now_s[0] = IDLE_S + 1.0
    _write_all(sqlite_store, [v for v in vehicles if not v.expires])
    with redis.Redis.from_url(redis_url) as client:
        client.flushdb()
        redis_store_ = RedisStore(redis_url, IDLE_S)
        _write_all(redis_store_, vehicles)
        for v in vehicles:
            if v.expires:
                client.pexpire(redis_store.SESSION_PREFIX + v.key, 1)
    time.sleep(0.005)
    return sqlite_store, redis_store_


def _inside(place: Place, box: Box | None, networks: tuple[str, ...]) -> bool:
    inside = box is None or (box[0] <= place.x <= box[2] and box[1] <= place.y <= box[3])
    return place.network in networks and inside


def _walk(store: StateStore, prefix: str, limit: int, networks: tuple[str, ...], box: Box | None) -> list:
    """Every page of a walk, cursor after cursor (the last key of a full page), until a page is not full."""
    pages, after = [], ""
    while True:
        page = store.placed(prefix, after, limit, networks, box)
        pages.append(page)
        if len(page) < limit:
            return pages
        after = page[-1].key


@pytest.mark.parametrize("probe_factor", [0, 10**9], ids=["along-keys", "from-index"])
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_the_redis_store_pages_the_places_as_sqlite_does(
    redis_url: str, monkeypatch: pytest.MonkeyPatch, probe_factor: int, data: st.DataObject
) -> None:
    monkeypatch.setattr(redis_store, "BOX_PROBE_FACTOR", probe_factor)
    kind, vehicles = data.draw(fleets())
    sqlite_store, redis_store_ = _stores(redis_url, vehicles)
    try:
        for _ in range(4):
            prefix = data.draw(st.sampled_from(["", "alpha/", "beta/"]))
            networks = tuple(data.draw(st.lists(st.sampled_from(NETWORKS), min_size=1, max_size=2, unique=True)))
            box = data.draw(st.none() | _boxes(kind, vehicles))
            limit = data.draw(st.integers(1, 6))
            after = data.draw(st.sampled_from(["", *(v.key for v in vehicles)]))
            assert redis_store_.placed(prefix, after, limit, networks, box) == sqlite_store.placed(
                prefix, after, limit, networks, box
            )
            walked = [p for page in _walk(redis_store_, prefix, limit, networks, box) for p in page]
            expected = sorted(
                (v.key, v.key.encode() + (b"+" if v.moved else b""), v.place)
                for v in vehicles
                if v.key.startswith(prefix) and not v.expires and _inside(v.place, box, networks)
            )
            assert [tuple(p) for p in walked] == expected
    finally:
        sqlite_store.close()
        redis_store_.close()


@settings(max_examples=300, deadline=None)
@given(
    st.tuples(*(st.floats(-1e7, 1e7) for _ in range(4))),
    st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
)
def test_every_point_of_a_box_is_in_its_ranges_of_cells(corners: tuple[float, ...], where: tuple[float, float]) -> None:
    x0, x1 = sorted(corners[::2])
    y0, y1 = sorted(corners[1::2])
    point = Place("town", x0 + where[0] * (x1 - x0), y0 + where[1] * (y1 - y0))
    point = Place("town", min(max(point.x, x0), x1), min(max(point.y, y0), y1))
    ranges = box_ranges((x0, y0, x1, y1))
    assert len(ranges) <= redis_store.BOX_SQUARES
    assert any(first <= place_cell(point) <= last for first, last in ranges)
    assert all(a[1] < b[0] for a, b in zip(ranges, ranges[1:], strict=False))  # sorted, apart
    assert place_cell(point) < 2**53  # exact as a score


@settings(max_examples=300)
@given(st.floats(allow_nan=False), st.floats(allow_nan=False))
def test_an_ordinal_never_decreases_as_its_coordinate_grows(a: float, b: float) -> None:
    low, high = sorted((a, b))
    assert 0 <= axis_ordinal(low) <= axis_ordinal(high) < 2**redis_store.AXIS_BITS


def test_a_small_box_reads_only_what_is_near_it_and_a_move_leaves_the_old_cell(redis_url: str) -> None:
    store = RedisStore(redis_url, IDLE_S)
    try:
        fleet = {f"alpha/{n:04d}": VehicleWrite(0, b"s", place=Place("town", 10.0 * n, 7.0)) for n in range(500)}
        store.write(fleet)
        old_box, new_box = (99.5, 6.5, 100.5, 7.5), (-1e4 - 0.5, -0.5, -1e4 + 0.5, 0.5)
        moved = Place("town", -1e4, 0.0)
        store.write({"alpha/0010": VehicleWrite(1, b"m", place=moved)})
        with redis.Redis.from_url(redis_url) as client:
            # The box's ranges of cells hold the vehicle near it only: the others are never read.
            near = {
                k
                for first, last in box_ranges(old_box)
                for k in client.zrangebyscore(GRID_PREFIX + "town", first, last)
            }
            assert near == set()
            assert [p.key for p in store.placed("", "", 10, ["town"], new_box)] == ["alpha/0010"]
            assert store.placed("", "", 10, ["town"], old_box) == []
            # A move to another network leaves the first network's index.
            store.write({"alpha/0010": VehicleWrite(2, b"w", place=Place("ring|west", 5.0, 5.0))})
            assert client.zscore(GRID_PREFIX + "town", "alpha/0010") is None
            assert client.zscore(GRID_PREFIX + "ring|west", "alpha/0010") is not None
    finally:
        store.close()


def test_expired_sessions_leave_the_index_when_a_read_meets_them_or_sweeps_them(redis_url: str) -> None:
    store = RedisStore(redis_url, IDLE_S)
    vehicles = 5 * redis_store.PLACES_SWEPT_PER_READ // 2
    try:
        store.write(
            {f"alpha/{n:04d}": VehicleWrite(0, b"s", place=Place("town", float(n), 0.0)) for n in range(vehicles)}
        )
        with redis.Redis.from_url(redis_url) as client:
            for n in range(0, vehicles, 2):
                client.pexpire(redis_store.SESSION_PREFIX + f"alpha/{n:04d}", 1)
            time.sleep(0.005)
            small_box = (-0.5, -1.0, 9.5, 1.0)
            in_box = store.placed("", "", 100, ["town"], small_box)
            assert [p.key for p in in_box] == [f"alpha/{n:04d}" for n in range(1, 10, 2)]
            # The five the box met are gone, and more: those the sweep checked after them.
            assert client.zcard(GRID_PREFIX + "town") < vehicles - 5
            # Reading the same small box again and again sweeps the whole placed set, round and round.
            for _ in range(3):
                assert store.placed("", "", 100, ["town"], small_box) == in_box
            live = vehicles // 2
            assert client.zcard(GRID_PREFIX + "town") == client.zcard(PLACED_KEY) == client.hlen(PLACES_KEY) == live
            assert [p.key for p in store.placed("", "", vehicles, ["town"], None)] == [
                f"alpha/{n:04d}" for n in range(1, vehicles, 2)
            ]
    finally:
        store.close()


def test_places_written_before_the_index_are_indexed_at_start_up(redis_url: str) -> None:
    store = RedisStore(redis_url, IDLE_S)
    try:
        places = {f"alpha/{n:04d}": Place("town", 3.0 * n, -2.0 * n) for n in range(2500)}
        store.write({key: VehicleWrite(0, b"s", place=place) for key, place in places.items()})
        with redis.Redis.from_url(redis_url) as client:
            # As a store without the index left them: places and keys, no cells.
            client.delete(GRID_PREFIX + "town")
            assert store.placed("", "", 10, ["town"], (2.5, -2.5, 3.5, -1.5)) == []
            moved = Place("town", 1e5, 1e5)
            store.write({"alpha/0007": VehicleWrite(1, b"m", place=moved)})
            store.check()
            assert client.get(GRID_BUILT_KEY) == b"1"
            assert client.zcard(GRID_PREFIX + "town") == 2500
            assert client.zscore(GRID_PREFIX + "town", "alpha/0007") == place_cell(moved)
        for key in ("alpha/0001", "alpha/2499"):
            x, y = places[key].x, places[key].y
            assert [p.key for p in store.placed("", "", 10, ["town"], (x - 0.5, y - 0.5, x + 0.5, y + 0.5))] == [key]
    finally:
        store.close()
