"""The state store in Redis: for replicas of the service on several machines.

Keys, in the database the URL names (``redis://HOST:PORT/DB``; give the service a database of
its own):

* ``csws:setting:{vehicle}``: ``1`` or ``0`` (the switch) followed by the category, if set;
  no expiry;
* ``csws:session:{vehicle}``: ``{version}|{session}``, expiring ``session_idle_s`` after its
  last write (Redis's key TTL: nothing to sweep).

A request reads its vehicles with one ``MGET`` (atomic) and writes them with one Lua script
(atomic, run by the server): per vehicle, it compares the session's version with the one read
and writes session and setting only if it matches.

Durability is Redis's: with ``appendonly yes`` and ``appendfsync always`` every write is on disk
before its reply, so no acknowledged ``PUT`` is lost when Redis or its machine fails; with
``appendfsync everysec`` the last second may be lost when the machine fails; without the
append-only file, everything since the last snapshot. Faults (refused or lost connections,
timeouts after :data:`service.store.STORE_TIMEOUT_S`, a Redis still loading or refusing writes)
are :class:`service.store.StoreUnavailable`.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import cast
from urllib.parse import urlsplit, urlunsplit

import redis
from redis.backoff import NoBackoff
from redis.retry import Retry

from csws.standard import Category

from . import STORE_TIMEOUT_S, StateStore, StoredVehicle, StoreUnavailable, VehicleSetting, VehicleWrite, checked_idle_s

__all__ = ["SESSION_PREFIX", "SETTING_PREFIX", "RedisStore"]

SESSION_PREFIX = "csws:session:"
SETTING_PREFIX = "csws:setting:"

#: KEYS: per vehicle its session key, then its setting key. ARGV: the sessions' time to live in
#: ms, then per vehicle the expected version, the new session and the new setting ('' for none).
#: Returns the (1-based) numbers of the vehicles whose session version had moved.
_WRITE_SCRIPT = """
local conflicts = {}
for vehicle = 1, #KEYS / 2 do
  local expected = ARGV[3 * vehicle - 1]
  local stored = redis.call('GET', KEYS[2 * vehicle - 1])
  local version = stored and string.match(stored, '^(%d+)|') or '0'
  if version == expected then
    redis.call('SET', KEYS[2 * vehicle - 1], (tonumber(version) + 1) .. '|' .. ARGV[3 * vehicle], 'PX', ARGV[1])
    if ARGV[3 * vehicle + 1] ~= '' then
      redis.call('SET', KEYS[2 * vehicle], ARGV[3 * vehicle + 1])
    end
  else
    conflicts[#conflicts + 1] = vehicle
  end
end
return conflicts
"""


def shown_url(url: str) -> str:
    """The URL as messages show it: without its password."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    user = f"{parts.username}:***@" if parts.username else ":***@"
    host = parts.hostname or ""
    return urlunsplit(parts._replace(netloc=f"{user}{host}" + (f":{parts.port}" if parts.port else "")))


def _encode_setting(setting: VehicleSetting) -> bytes:
    return (("1" if setting.switched_on else "0") + (setting.category.value if setting.category else "")).encode()


def _decode_setting(value: bytes) -> VehicleSetting:
    """A stored setting; ValueError for one this service did not write."""
    text = value.decode()
    if text[:1] not in ("0", "1"):
        raise ValueError(f"not a vehicle setting: {text[:40]!r}")
    return VehicleSetting(text[0] == "1", Category(text[1:]) if text[1:] else None)


def _decode_session(value: bytes | None) -> tuple[bytes | None, int]:
    """A stored session and its version."""
    if value is None:
        return None, 0
    version, _, session = value.partition(b"|")
    return session, int(version)


class RedisStore(StateStore):
    """Settings and sessions in Redis.

    Parameters
    ----------
    url
        ``redis://[[USER]:PASSWORD@]HOST:PORT/DB`` (``rediss://`` for TLS, ``unix://PATH?db=DB``).
    idle_s
        A session not written for this long expires (its key's TTL), s.

    Raises
    ------
    ValueError
        If the URL is malformed.
    """

    def __init__(self, url: str, idle_s: float) -> None:
        idle_s = checked_idle_s(idle_s)
        self.name = shown_url(url)
        self.ttl_ms = max(1, round(idle_s * 1000.0))
        try:
            # One immediate retry on a broken connection (one the pool kept across a restart of
            # Redis), none on a timeout: a request waits at most about STORE_TIMEOUT_S for its answer.
            self._redis = redis.Redis.from_url(
                url,
                socket_timeout=STORE_TIMEOUT_S,
                socket_connect_timeout=STORE_TIMEOUT_S,
                retry=Retry(NoBackoff(), 1, supported_errors=(redis.ConnectionError,)),
            )
        except ValueError as exc:
            raise ValueError(f"bad Redis URL {self.name}: {exc}") from None
        self._database = int(self._redis.connection_pool.connection_kwargs.get("db", 0))
        self._write_script = self._redis.register_script(_WRITE_SCRIPT)

    def _unavailable(self, exc: Exception) -> StoreUnavailable:
        return StoreUnavailable(f"the state store {self.name} cannot be reached now: {type(exc).__name__}: {exc}")

    def check(self) -> None:
        try:
            self._redis.ping()
        except redis.RedisError as exc:
            raise OSError(f"cannot reach the state store {self.name}: {exc}") from None

    def _values(self, keys: Sequence[str | bytes]) -> list[bytes | None]:
        """The values of ``keys`` in one ``MGET`` (the client decodes no responses: they are bytes)."""
        return cast(list[bytes | None], self._redis.mget(keys))

    def read(self, vehicle_ids: Collection[str]) -> dict[str, StoredVehicle]:
        if not vehicle_ids:
            return {}
        vehicle_ids = list(vehicle_ids)
        keys = [SESSION_PREFIX + v for v in vehicle_ids] + [SETTING_PREFIX + v for v in vehicle_ids]
        try:
            values = self._values(keys)
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        count = len(vehicle_ids)
        stored = {}
        for vehicle_id, session, setting in zip(vehicle_ids, values[:count], values[count:], strict=False):
            try:
                stored[vehicle_id] = StoredVehicle(
                    None if setting is None else _decode_setting(setting), *_decode_session(session)
                )
            except ValueError as exc:
                raise StoreUnavailable(
                    f"the state store {self.name} holds an unreadable entry of vehicle {vehicle_id!r}: {exc}"
                ) from None
        return stored

    def write(self, writes: Mapping[str, VehicleWrite]) -> set[str]:
        if not writes:
            return set()
        vehicle_ids = list(writes)
        keys: list[str] = []
        args: list[int | bytes] = [self.ttl_ms]
        for vehicle_id in vehicle_ids:
            w = writes[vehicle_id]
            keys += [SESSION_PREFIX + vehicle_id, SETTING_PREFIX + vehicle_id]
            args += [w.expected_version, w.session, b"" if w.setting is None else _encode_setting(w.setting)]
        try:
            conflicts = self._write_script(keys=keys, args=args)
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        return {vehicle_ids[number - 1] for number in conflicts}

    def sessions(self, prefix: str = "") -> dict[str, bytes]:
        """Found with ``SCAN`` (the keys of the pattern, a batch at a time) and read with one ``MGET``: a
        session written between the two is read as written, one that expired between them is left out."""
        pattern = SESSION_PREFIX + prefix + "*"  # fleet names hold no glob characters (service.keys)
        try:
            keys = list(self._redis.scan_iter(match=pattern, count=1000))
            values = self._values(keys) if keys else []
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        found = {}
        for key, value in zip(keys, values, strict=False):
            session, _version = _decode_session(value)
            if session is not None:
                found[key.decode()[len(SESSION_PREFIX) :]] = session
        return found

    def session_count(self) -> int:
        """The keys with a TTL in the service's database: its sessions (a database of its own).
        Counted by Redis as it goes (``INFO keyspace``), so keys that have just expired may
        still count until Redis reclaims them."""
        try:
            keyspace = self._redis.info("keyspace")
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        return int(keyspace.get(f"db{self._database}", {}).get("expires", 0))

    def close(self) -> None:
        self._redis.close()
