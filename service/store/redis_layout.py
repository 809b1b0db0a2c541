"""How the Redis store lays its state out: the keys, the two Lua scripts that read and write a group of
vehicles, and the values they take and give (:mod:`service.store.redis` describes the keys and runs them).

A script takes a group's vehicles packed in two values (:func:`packed`: their lengths, 4 bytes each, and their
bytes one after the other), and the read script answers the same way (:func:`unpacked`), so that the client packs
and parses one value, not a few per vehicle. The stored values are those of earlier versions, so a Redis shared
with their processes keeps working.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

from csws.standard import Category

from . import Place, VehicleSetting, VehicleWrite
from .redis_places import GRID_PREFIX, place_cell

__all__ = [
    "SESSION_PREFIX",
    "SETTING_PREFIX",
    "PLACES_KEY",
    "PLACED_KEY",
    "OUTBOX_KEY",
    "HISTORY_PREFIX",
    "HISTORIES_KEY",
    "EVENT_SEQ_PREFIX",
    "WRITE_SCRIPT",
    "READ_SCRIPT",
    "encode_setting",
    "decode_setting",
    "encode_place",
    "decode_place",
    "packed",
    "unpacked",
    "vehicle_fields",
    "decode_session",
]

SESSION_PREFIX = "csws:session:"
SETTING_PREFIX = "csws:setting:"
PLACES_KEY = "csws:places"
PLACED_KEY = "csws:placed"
OUTBOX_KEY = "csws:outbox"
HISTORY_PREFIX = "csws:history:"
HISTORIES_KEY = "csws:histories"
EVENT_SEQ_PREFIX = "csws:event-seq:"

#: KEYS: the places hash and the placed set.
#: ARGV: the sessions' time to live in ms, the longest retention of events in ms, the vehicles packed in two values
#: (:func:`packed` of :func:`vehicle_fields`: per vehicle its key, the expected version, the new session, the new
#: setting ('' for none), the new place ('' for none) and its cell (:func:`place_cell`)), then per event the
#: (1-based) number of its vehicle, its fleet, number, time (s), JSON and its fleet's retention in ms. Two packed values
#: instead of 8 arguments a vehicle: the client packs 4 arguments, not thousands.
#: Returns the numbers of the vehicles whose session version had moved (none of their events is added).
WRITE_SCRIPT = (
    """
local conflicts, written = {}, {}
local lengths, packed, length_at, at, vehicle = ARGV[3], ARGV[4], 1, 1, 0
local function field()
  local length = struct.unpack('>I4', lengths, length_at)
  local value = string.sub(packed, at, at + length - 1)
  length_at, at = length_at + 4, at + length
  return value
end
while length_at <= #lengths do
  vehicle = vehicle + 1
  local key, expected, session, setting, place, cell = field(), field(), field(), field(), field(), field()
  local session_key = '__SESSION__' .. key
  local stored = redis.call('GET', session_key)
  local version = stored and string.match(stored, '^(%d+)|') or '0'
  if version == expected then
    written[vehicle] = key
    redis.call('SET', session_key, (tonumber(version) + 1) .. '|' .. session, 'PX', ARGV[1])
    if setting ~= '' then
      redis.call('SET', '__SETTING__' .. key, setting)
    end
    if place ~= '' then
      local network = string.sub(place, 1, string.find(place, '|[^|]+|[^|]+$') - 1)
      local stored_place = redis.call('HGET', KEYS[1], key)
      local left = stored_place and string.sub(stored_place, 1, string.find(stored_place, '|[^|]+|[^|]+$') - 1)
      if left and left ~= network then
        redis.call('ZREM', '__GRID__' .. left, key)
      end
      redis.call('HSET', KEYS[1], key, place)
      if not stored_place then
        redis.call('ZADD', KEYS[2], 0, key)
      end
      redis.call('ZADD', '__GRID__' .. network, cell, key)
    end
  else
    conflicts[#conflicts + 1] = vehicle
  end
end
local first = 5
if first <= #ARGV then
  local now = redis.call('TIME')
  local now_s = tonumber(now[1]) + tonumber(now[2]) / 1e6
  local longest_ms = tonumber(ARGV[2])
  local oldest_s = now_s - longest_ms / 1000
  for at = first, #ARGV, 6 do
    local key = written[tonumber(ARGV[at])]
    if key then
      local fleet, seq, time_s, body = ARGV[at + 1], ARGV[at + 2], ARGV[at + 3], ARGV[at + 4]
      local retention_ms = tonumber(ARGV[at + 5])
      local oldest_id = tostring(math.floor(now_s * 1000 - retention_ms))
      local longest_id = tostring(math.floor(now_s * 1000 - longest_ms))
      local id = redis.call('XADD', '__OUTBOX__', 'MINID', longest_id, '*', 'k', key, 'b', body)
      redis.call('XADD', '__OUTBOX__:' .. fleet, 'MINID', oldest_id, id, 'k', key, 'b', body)
      local history = '__HISTORY__' .. key
      local ms, sequence = string.match(id, '^(%d+)-(%d+)$')
      redis.call('ZADD', history, time_s, string.format('%s-%020d|', ms, tonumber(sequence)) .. body)
      for _, old in ipairs(redis.call('ZRANGE', history, 0, 15)) do
        if tonumber(string.match(old, '^(%d+)-')) < tonumber(oldest_id) then
          redis.call('ZREM', history, old)
        end
      end
      redis.call('ZADD', '__HISTORIES__', now_s + (retention_ms - longest_ms) / 1000, key)
      redis.call('SET', '__SEQ__' .. key, seq)
    end
  end
  for _, stale in ipairs(redis.call('ZRANGEBYSCORE', '__HISTORIES__', '-inf', '(' .. oldest_s, 'LIMIT', 0, 16)) do
    redis.call('DEL', '__HISTORY__' .. stale)
    redis.call('ZREM', '__HISTORIES__', stale)
  end
end
return conflicts
""".replace("__OUTBOX__", OUTBOX_KEY)
    .replace("__HISTORY__", HISTORY_PREFIX)
    .replace("__HISTORIES__", HISTORIES_KEY)
    .replace("__SEQ__", EVENT_SEQ_PREFIX)
    .replace("__GRID__", GRID_PREFIX)
    .replace("__SESSION__", SESSION_PREFIX)
    .replace("__SETTING__", SETTING_PREFIX)
)
#: ARGV: the vehicles' keys packed in two values (:func:`packed`). Returns the session, the setting and the number
#: of the last event of each vehicle, in that order, packed the same way, a length of -1 standing for a key that
#: does not exist (:func:`unpacked`). Atomic as the ``MGET`` it makes is; two arguments and two values in the reply
#: instead of 3 keys and 3 values a vehicle, which redis-py packed and parsed one by one.
READ_SCRIPT = (
    """
local lengths, packed, length_at, at, keys = ARGV[1], ARGV[2], 1, 1, {}
while length_at <= #lengths do
  local length = struct.unpack('>I4', lengths, length_at)
  local key = string.sub(packed, at, at + length - 1)
  length_at, at = length_at + 4, at + length
  keys[#keys + 1] = '__SESSION__' .. key
  keys[#keys + 1] = '__SETTING__' .. key
  keys[#keys + 1] = '__SEQ__' .. key
end
local out_lengths, out = {}, {}
for first = 1, #keys, 3000 do
  for _, value in ipairs(redis.call('MGET', unpack(keys, first, math.min(first + 2999, #keys)))) do
    out_lengths[#out_lengths + 1] = struct.pack('>i4', value and #value or -1)
    out[#out + 1] = value or ''
  end
end
return {table.concat(out_lengths), table.concat(out)}
""".replace("__SESSION__", SESSION_PREFIX)
    .replace("__SETTING__", SETTING_PREFIX)
    .replace("__SEQ__", EVENT_SEQ_PREFIX)
)


def encode_setting(setting: VehicleSetting) -> bytes:
    return (("1" if setting.switched_on else "0") + (setting.category.value if setting.category else "")).encode()


def decode_setting(value: bytes) -> VehicleSetting:
    """A stored setting; ValueError for one this service did not write."""
    text = value.decode()
    if text[:1] not in ("0", "1"):
        raise ValueError(f"not a vehicle setting: {text[:40]!r}")
    return VehicleSetting(text[0] == "1", Category(text[1:]) if text[1:] else None)


def encode_place(place: Place) -> str:
    """A place as the store keeps it: ``{network}|{x}|{y}``, the numbers exact (``repr``)."""
    return f"{place.network}|{place.x!r}|{place.y!r}"


def decode_place(value: bytes) -> Place:
    """A stored place (network names may hold ``|``; the numbers do not)."""
    network, x, y = value.decode().rsplit("|", 2)
    return Place(network, float(x), float(y))


def packed(values: Sequence[bytes]) -> tuple[bytes, bytes]:
    """``values`` as the scripts unpack them, in two values: their lengths (4 bytes each, big-endian), and their
    bytes one after the other."""
    return struct.pack(f">{len(values)}I", *map(len, values)), b"".join(values)


def unpacked(lengths: bytes, packed: bytes) -> list[bytes | None]:
    """The values the read script packed (their lengths, 4 bytes each, big-endian and signed: -1 for a key that does
    not exist; and their bytes one after the other), None for a key that does not exist."""
    values: list[bytes | None] = []
    at = 0
    for length in struct.unpack(f">{len(lengths) // 4}i", lengths):
        if length < 0:
            values.append(None)
        else:
            values.append(packed[at : at + length])
            at += length
    return values


def vehicle_fields(vehicle_id: str, w: VehicleWrite) -> tuple[bytes, ...]:
    """What the write script takes of one vehicle: its key, expected version, session, setting, place and cell
    (the last three empty for none)."""
    return (
        vehicle_id.encode(),
        str(w.expected_version).encode(),
        w.session,
        b"" if w.setting is None else encode_setting(w.setting),
        b"" if w.place is None else encode_place(w.place).encode(),
        b"" if w.place is None else str(place_cell(w.place)).encode(),
    )


def decode_session(value: bytes | None) -> tuple[bytes | None, int]:
    """A stored session and its version."""
    if value is None:
        return None, 0
    version, _, session = value.partition(b"|")
    return session, int(version)
