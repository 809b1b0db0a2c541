"""The Redis store's spatial index of the places (:mod:`service.store.redis`): cells, boxes and the scripts
that read places.

Each place is indexed in the sorted set ``csws:grid:{network}`` by its cell, written by the script that
writes its session; reading places (:meth:`service.store.redis.RedisStore.placed`) is one server-side
script. A cell is a point of a quadtree over both axes: each coordinate is mapped to a 26-bit ordinal
that never decreases as the coordinate grows (:func:`axis_ordinal`: fine steps near zero, then steps
relative to the value, like a floating-point number's, so that one mapping serves lon/lat and network
metres alike), and the two ordinals are interleaved (a Morton code, 52 bits: exact as a score). Every
quadtree square is then one range of scores, and a box is read as at most :data:`BOX_SQUARES` squares
(:func:`box_ranges`). When these hold fewer than :data:`BOX_PROBE_FACTOR` places per vehicle asked for
(``ZCOUNT``), the script reads their vehicles, checks their exact places against the box and the
networks, sorts them by key (in a scratch sorted set of equal scores: Redis orders it by bytes, not by
Lua's locale) and reads them from the cursor on, so that a small box over a large fleet reads only the
places near it. Otherwise (no box, or a large one) it walks the fleet's keys in order from the cursor, a
thousand at a time, keeping those whose place is on the networks and in the box, until the page is full:
a page then costs about what it passes, not what the box holds (100,000 places: a 1 x 1 m box in under 5
ms rather than 0.3 to 0.7 s, ``python -m benchmarks.fleet --redis``).
"""

from __future__ import annotations

import math

from . import Box, Place

__all__ = [
    "GRID_PREFIX",
    "PLACED_SCRATCH_KEY",
    "GRID_BUILT_KEY",
    "PLACES_SWEPT_KEY",
    "PLACES_SWEPT_PER_READ",
    "AXIS_BITS",
    "BOX_SQUARES",
    "BOX_PROBE_FACTOR",
    "PLACED_SCRIPT",
    "INDEX_SCRIPT",
    "axis_ordinal",
    "place_cell",
    "box_ranges",
]

GRID_PREFIX = "csws:grid:"
#: A sorted set the read of a box sorts its vehicles in, emptied before the script ends.
PLACED_SCRATCH_KEY = "csws:placed-scratch"
#: Set once the places written before the spatial index existed are in it (:meth:`RedisStore.check`).
GRID_BUILT_KEY = "csws:grid-built"
#: The last vehicle whose session a read of places checked on its sweep.
PLACES_SWEPT_KEY = "csws:places-swept"
#: How many vehicles of the placed set each read of places checks for an expired session, besides those it
#: meets: the places of expired sessions leave the index (and the hash) even when only small boxes are read.
PLACES_SWEPT_PER_READ = 100
#: Bits of a coordinate's ordinal (:func:`axis_ordinal`): two interleaved (52 bits) are exact in a score (a double).
AXIS_BITS = 26
#: Bits of an ordinal below each power of two (its steps are 2**-19 of the power), and the first power with such steps.
_STEP_BITS = 19
_FIRST_POWER = 1.0
#: Larger magnitudes share the last ordinal of their sign.
_LARGEST = 2.0**62
_ZERO = 1 << (AXIS_BITS - 1)
#: A box is read as at most this many quadtree squares (:func:`box_ranges`): each costs the script two
#: look-ups in a sorted set per network, and more of them follow the box's edges more closely.
BOX_SQUARES = 64
#: A box whose squares hold at least this many places per vehicle asked for is read in key order, as a
#: page without a box, checking each place: sorting every place of a large box for each page would cost
#: what the box holds, not what the page does (the SQLite store's rule).
BOX_PROBE_FACTOR = 4

#: KEYS: the places hash, the placed set, the scratch set and the sweep's key. ARGV: the first key and the
#: end of the key range (as ZRANGEBYLEX takes them), the page's size, '1' with a box else '0', the box (min x, min y,
#: max x, max y), the most places its squares may hold to be read from the index, the number of networks,
#: the networks, then the box's ranges of cells (first, last). Returns key, stored session and place of
#: each vehicle found, flat; takes out the places whose session expired. ``__SESSION__`` stands for the
#: sessions' key prefix (:data:`service.store.redis.SESSION_PREFIX`).
PLACED_SCRIPT = """
local limit, boxed, found = tonumber(ARGV[3]), ARGV[4] == '1', {}
local min_x, min_y, max_x, max_y = tonumber(ARGV[5]), tonumber(ARGV[6]), tonumber(ARGV[7]), tonumber(ARGV[8])
local networks, names = {}, {}
for i = 11, 10 + tonumber(ARGV[10]) do
  networks[ARGV[i]] = true
  names[#names + 1] = ARGV[i]
end
local first_range = 11 + tonumber(ARGV[10])

local function parsed(place)
  local bar, _, x, y = string.find(place or '', '|([^|]+)|([^|]+)$')
  if not bar then return nil end
  return string.sub(place, 1, bar - 1), tonumber(x), tonumber(y)
end

local function wanted(network, x, y)
  return network and networks[network] and (not boxed or (x >= min_x and x <= max_x and y >= min_y and y <= max_y))
end

-- Adds a vehicle if its session is live, else takes its place out; whether the page is full.
-- Takes out the place of a vehicle whose session expired.
local function forget(key, network)
  redis.call('ZREM', KEYS[2], key)
  redis.call('HDEL', KEYS[1], key)
  if network then redis.call('ZREM', '__GRID__' .. network, key) end
end

local function take(key, place, network)
  local session = redis.call('GET', '__SESSION__' .. key)
  if session then
    found[#found + 1] = key
    found[#found + 1] = session
    found[#found + 1] = place
  else
    forget(key, network)
  end
  return #found == 3 * limit
end

-- Checks the next keys of the placed set (from where the last read stopped, round and round) for
-- sessions that expired, so that their places leave whatever boxes the reads ask for.
local function sweep()
  local last = redis.call('GET', KEYS[4])
  local keys = redis.call('ZRANGEBYLEX', KEYS[2], last and '(' .. last or '-', '+', 'LIMIT', 0, __SWEPT__)
  if #keys < __SWEPT__ then
    redis.call('DEL', KEYS[4])
  else
    redis.call('SET', KEYS[4], keys[#keys])
  end
  for _, key in ipairs(keys) do
    if redis.call('EXISTS', '__SESSION__' .. key) == 0 then
      forget(key, (parsed(redis.call('HGET', KEYS[1], key))))
    end
  end
end

-- Reads the keys of a sorted set of equal scores in order from the cursor, a thousand at a time,
-- taking those whose place is wanted until the page is full (places: by key, nil to read them).
local function walk(set, places)
  local low = ARGV[1]
  while true do
    local keys = redis.call('ZRANGEBYLEX', set, low, ARGV[2], 'LIMIT', 0, 1000)
    if #keys == 0 then return end
    local known = places
    if not known then
      known = {}
      for i, place in ipairs(redis.call('HMGET', KEYS[1], unpack(keys))) do known[keys[i]] = place end
    end
    for _, key in ipairs(keys) do
      local place = known[key]
      local network, x, y = parsed(place)
      if wanted(network, x, y) and take(key, place, network) then return end
    end
    low = '(' .. keys[#keys]
  end
end

-- The places of the box's cells that are in the box, by key; nil when the cells hold too many.
local function boxed_places()
  local count = 0
  for _, network in ipairs(names) do
    for i = first_range, #ARGV, 2 do
      count = count + redis.call('ZCOUNT', '__GRID__' .. network, ARGV[i], ARGV[i + 1])
    end
  end
  if count >= tonumber(ARGV[9]) then return nil end
  local places = {}
  for _, network in ipairs(names) do
    for i = first_range, #ARGV, 2 do
      local offset = 0
      while true do
        local keys = redis.call('ZRANGEBYSCORE', '__GRID__' .. network, ARGV[i], ARGV[i + 1], 'LIMIT', offset, 1000)
        if #keys == 0 then break end
        for j, place in ipairs(redis.call('HMGET', KEYS[1], unpack(keys))) do
          if wanted(parsed(place)) then
            places[keys[j]] = place
            redis.call('ZADD', KEYS[3], 0, keys[j])
          end
        end
        offset = offset + #keys
      end
    end
  end
  return places
end

redis.call('DEL', KEYS[3])
local places = boxed and boxed_places()
if places then
  walk(KEYS[3], places)
  redis.call('DEL', KEYS[3])
else
  walk(KEYS[2], nil)
end
sweep()
return found
""".replace("__GRID__", GRID_PREFIX).replace("__SWEPT__", str(PLACES_SWEPT_PER_READ))

#: KEYS: the places hash. ARGV: per place its vehicle, its place as read and its cell. Indexes each place
#: that is still the one read and not yet indexed (a write since then indexed the new one).
INDEX_SCRIPT = """
for at = 1, #ARGV, 3 do
  local place = ARGV[at + 1]
  if redis.call('HGET', KEYS[1], ARGV[at]) == place then
    local network = string.sub(place, 1, string.find(place, '|[^|]+|[^|]+$') - 1)
    redis.call('ZADD', '__GRID__' .. network, 'NX', ARGV[at + 2], ARGV[at])
  end
end
""".replace("__GRID__", GRID_PREFIX)


def axis_ordinal(value: float) -> int:
    """The ordinal of a coordinate on its axis, in ``[0, 2**AXIS_BITS)``, never decreasing as the coordinate grows.

    Magnitudes below 1 are cut into 2**19 equal steps; each power of two above into 2**19 steps (of
    2**-19 of it, as a floating-point number's are): about 7 m in latitude and 1 m in longitude near
    8 degrees, 2 cm at 10 km of network metres. Negative coordinates mirror the positive ones below
    zero's ordinal; magnitudes from 2**62 share the last ordinal.

    Parameters
    ----------
    value
        A coordinate (degrees or metres).
    """
    magnitude = min(abs(value), _LARGEST)
    if magnitude < _FIRST_POWER:
        steps = int(magnitude * (1 << _STEP_BITS))
    else:
        fraction, exponent = math.frexp(magnitude)
        steps = (exponent << _STEP_BITS) + int((2.0 * fraction - 1.0) * (1 << _STEP_BITS))
    return _ZERO + steps if value >= 0.0 else _ZERO - 1 - steps


def _spread(ordinal: int) -> int:
    """The bits of an ordinal of :data:`AXIS_BITS` bits moved to the even bits: half of a Morton code."""
    ordinal = (ordinal | ordinal << 16) & 0x0000FFFF0000FFFF
    ordinal = (ordinal | ordinal << 8) & 0x00FF00FF00FF00FF
    ordinal = (ordinal | ordinal << 4) & 0x0F0F0F0F0F0F0F0F
    ordinal = (ordinal | ordinal << 2) & 0x3333333333333333
    return (ordinal | ordinal << 1) & 0x5555555555555555


def place_cell(place: Place) -> int:
    """The cell of a place in the spatial index: the Morton code of its two ordinals (:func:`axis_ordinal`),
    x on the even bits, y on the odd ones."""
    return _spread(axis_ordinal(place.x)) | _spread(axis_ordinal(place.y)) << 1


def _square_range(level: int, square_x: int, square_y: int) -> tuple[int, int]:
    """The cells (first, last) of a quadtree square: the ordinals ``[square << level, (square + 1) << level)``
    on each axis are one range of Morton codes."""
    code = _spread(square_x) | _spread(square_y) << 1
    return code << 2 * level, ((code + 1) << 2 * level) - 1


def box_ranges(box: Box) -> list[tuple[int, int]]:
    """The ranges of cells (first, last) whose places may be in a box, adjacent ranges joined; none for a
    box whose minimum exceeds its maximum.

    The box's ordinals (:func:`axis_ordinal`) are covered by quadtree squares, those across its edges
    split into their quarters that meet it, one level after the other, as long as the squares are at
    most :data:`BOX_SQUARES`; squares inside the box stay whole. Each square is one range of Morton
    codes (:func:`place_cell`), so the places read beyond the box are those of the edges' squares.
    """
    low_x, low_y, high_x, high_y = (axis_ordinal(value) for value in box)

    def meets(level: int, x: int, y: int) -> bool:
        return (
            x << level <= high_x and ((x + 1) << level) > low_x and y << level <= high_y and ((y + 1) << level) > low_y
        )

    def inside(level: int, x: int, y: int) -> bool:
        return (
            x << level >= low_x
            and ((x + 1) << level) <= high_x + 1
            and y << level >= low_y
            and ((y + 1) << level) <= high_y + 1
        )

    level, across = AXIS_BITS, [(0, 0)] if meets(AXIS_BITS, 0, 0) else []
    ranges: list[tuple[int, int]] = []
    while across and level > 0:
        quarters = [(2 * x + i, 2 * y + j) for x, y in across for i in (0, 1) for j in (0, 1)]
        quarters = [(x, y) for x, y in quarters if meets(level - 1, x, y)]
        if len(ranges) + len(quarters) > BOX_SQUARES:
            break
        level -= 1
        ranges += [_square_range(level, x, y) for x, y in quarters if inside(level, x, y)]
        across = [(x, y) for x, y in quarters if not inside(level, x, y)]
    joined: list[tuple[int, int]] = []
    for first, last in sorted(ranges + [_square_range(level, x, y) for x, y in across]):
        if joined and joined[-1][1] + 1 == first:
            joined[-1] = (joined[-1][0], last)
        else:
            joined.append((first, last))
    return joined
