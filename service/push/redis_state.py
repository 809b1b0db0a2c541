"""Push's durable state in Redis, for replicas on several machines that share one Redis (``--state redis://``).

The same as :class:`service.push.state.PushState` (cursors, the queue of events waiting for a retry,
the dead letters, the leases), in keys of its own under ``csws:push:``:

* ``cursor:{sink}``: a sink's cursor in the outbox;
* ``item:{number}``: a queued event (hash: sink, vehicle, body, tries, next_try_s, queued_s, error), numbered
  by ``number`` in the order queued;
* ``queue:{sink}:{vehicle}``: the numbers of a vehicle's queued events, oldest first;
* ``heads:{sink}``: the vehicles with events queued, scored by the next try of their first;
* ``count:{sink}``: how many events wait; ``dead``: the dead letters (JSON, oldest first);
* ``lease:{name}``: the holder of a lease, expiring with it.

Only the lease's holder writes the queue, so plain transactions suffice; the lease itself is taken
and renewed by one script, atomically.
"""

from __future__ import annotations

import json

import redis

from .state import DeadLetter, Pending, QueuedRow

__all__ = ["RedisPushState", "PREFIX"]

PREFIX = "csws:push:"
#: Take the lease KEYS[1] for ARGV[1] for ARGV[2] ms when it is free or already its own; 1 when held.
_HOLD = """
local holder = redis.call('GET', KEYS[1])
if holder == false or holder == ARGV[1] then
    redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2])
    return 1
end
return 0
"""
#: Give the lease KEYS[1] up if ARGV[1] holds it.
_RELEASE = """
if redis.call('GET', KEYS[1]) == ARGV[1] then
    return redis.call('DEL', KEYS[1])
end
return 0
"""


class RedisPushState:
    """Push's durable state in the Redis at ``url`` (see the module); the interface of ``PushState``."""

    def __init__(self, url: str) -> None:
        self.path = url
        self._redis = redis.Redis.from_url(url, socket_timeout=10.0)
        self._hold = self._redis.register_script(_HOLD)
        self._release = self._redis.register_script(_RELEASE)

    def close(self) -> None:
        """Close the connections."""
        self._redis.close()

    def cursor(self, sink: str) -> str | None:
        """Up to where the outbox went to ``sink`` (delivered or queued), None before its first event."""
        value = self._redis.get(PREFIX + "cursor:" + sink)
        return value.decode() if isinstance(value, bytes) else None

    def advance(self, sink: str, cursor: str, queued: list[QueuedRow], now_s: float) -> None:
        """Queue events (sink, vehicle, body, tries, next try, error) and move the cursor of ``sink``, at once."""
        first = int(self._redis.incrby(PREFIX + "number", len(queued))) - len(queued) + 1 if queued else 0
        heads = {(row[0], row[1]) for row in queued if not self._redis.exists(_queue(row[0], row[1]))}
        with self._redis.pipeline(transaction=True) as pipe:
            for number, (row_sink, vehicle, body, tries, next_s, error) in enumerate(queued, start=first):
                pipe.hset(
                    PREFIX + f"item:{number}",
                    mapping={
                        "sink": row_sink,
                        "vehicle": vehicle,
                        "body": body,
                        "tries": tries,
                        "next_try_s": next_s,
                        "queued_s": now_s,
                        "error": error,
                    },
                )
                pipe.rpush(_queue(row_sink, vehicle), number)
                pipe.incr(PREFIX + "count:" + row_sink)
                if (row_sink, vehicle) in heads:
                    pipe.zadd(PREFIX + "heads:" + row_sink, {vehicle: next_s})
                    heads.discard((row_sink, vehicle))
            pipe.set(PREFIX + "cursor:" + sink, cursor)
            pipe.execute()

    def waiting_vehicles(self, sink: str) -> set[str]:
        """The vehicles with events queued for ``sink``: their later events go behind them."""
        return {_text(member) for member in self._redis.zrange(PREFIX + "heads:" + sink, 0, -1)}

    def due(self, sink: str, now_s: float, limit: int) -> list[Pending]:
        """The first queued event of each vehicle of ``sink`` whose next try is due, oldest first."""
        vehicles = self._redis.zrangebyscore(PREFIX + "heads:" + sink, "-inf", now_s, start=0, num=limit)
        found = []
        for vehicle in vehicles:
            head = self._redis.lindex(_queue(sink, _text(vehicle)), 0)
            if head is not None:
                found.append(self._pending(int(head)))
        return sorted(found)

    def queued_count(self, sink: str) -> int:
        """How many events wait for ``sink``."""
        return int(self._redis.get(PREFIX + "count:" + sink) or 0)

    def delivered(self, number: int) -> None:
        """A queued event went out: off the queue."""
        self._remove(self._pending(number))

    def failed(self, number: int, tries: int, next_try_s: float, error: str) -> None:
        """A queued event failed again: its tries so far and when to try next."""
        pending = self._pending(number)
        with self._redis.pipeline(transaction=True) as pipe:
            pipe.hset(PREFIX + f"item:{number}", mapping={"tries": tries, "next_try_s": next_try_s, "error": error})
            pipe.zadd(PREFIX + "heads:" + pending.sink, {pending.vehicle: next_try_s})
            pipe.execute()

    def dead(self, pending: Pending, tries: int, error: str, now_s: float) -> None:
        """Give a queued event up: off the queue, into the dead letters."""
        letter = {
            "sink": pending.sink,
            "vehicle": pending.vehicle,
            "body": pending.body.decode(),
            "tries": tries,
            "error": error,
            "dead_s": now_s,
        }
        self._redis.rpush(PREFIX + "dead", json.dumps(letter))
        self._remove(pending)

    def dead_letters(self, sink_prefix: str = "", limit: int = 1000) -> list[DeadLetter]:
        """The dead letters of the sinks whose names start with ``sink_prefix``, oldest first."""
        letters = []
        for number, raw in enumerate(self._redis.lrange(PREFIX + "dead", 0, -1), start=1):
            letter = json.loads(raw)
            if letter["sink"].startswith(sink_prefix):
                letters.append(
                    DeadLetter(
                        number,
                        letter["sink"],
                        letter["vehicle"],
                        letter["body"].encode(),
                        letter["tries"],
                        letter["error"],
                        letter["dead_s"],
                    )
                )
        return letters[:limit]

    def hold_lease(self, name: str, holder: str, now_s: float, duration_s: float) -> bool:
        """Take or renew the lease ``name`` for ``holder`` for ``duration_s`` (Redis' own clock expires it)."""
        return bool(self._hold(keys=[PREFIX + "lease:" + name], args=[holder, max(1, int(duration_s * 1000))]))

    def release_lease(self, name: str, holder: str) -> None:
        """Give the lease up at once, if ``holder`` holds it."""
        self._release(keys=[PREFIX + "lease:" + name], args=[holder])

    def _pending(self, number: int) -> Pending:
        """The queued event ``number``."""
        item = {_text(key): value for key, value in self._redis.hgetall(PREFIX + f"item:{number}").items()}
        return Pending(
            number,
            _text(item["sink"]),
            _text(item["vehicle"]),
            item["body"] if isinstance(item["body"], bytes) else item["body"].encode(),
            int(item["tries"]),
            float(item["next_try_s"]),
            float(item["queued_s"]),
            _text(item["error"]),
        )

    def _remove(self, pending: Pending) -> None:
        """Take a vehicle's first queued event off its queue; its next one (if any) becomes its first."""
        queue = _queue(pending.sink, pending.vehicle)
        with self._redis.pipeline(transaction=True) as pipe:
            pipe.lrem(queue, 1, str(pending.number))
            pipe.delete(PREFIX + f"item:{pending.number}")
            pipe.decr(PREFIX + "count:" + pending.sink)
            pipe.lindex(queue, 0)
            head = pipe.execute()[-1]
        if head is None:
            self._redis.zrem(PREFIX + "heads:" + pending.sink, pending.vehicle)
        else:
            next_s = float(self._redis.hget(PREFIX + f"item:{int(head)}", "next_try_s") or 0.0)
            self._redis.zadd(PREFIX + "heads:" + pending.sink, {pending.vehicle: next_s})


def _queue(sink: str, vehicle: str) -> str:
    """The key of a vehicle's queue of events for ``sink``."""
    return PREFIX + f"queue:{sink}:{vehicle}"


def _text(value: object) -> str:
    """A value Redis answered (bytes) as text."""
    return value.decode() if isinstance(value, bytes) else str(value)
