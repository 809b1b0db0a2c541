"""Keeps what a road map reads of a SUMO network, so that a network read once loads without being parsed again.

Of Bad Hersfeld's load from the profile cache (some 3.7 s), about 2 s are the network itself: sumolib's parse of
its 12,752 lanes and their connections, then the lanes' records, successors and the road's continuations
(:func:`csws.road.network.net_lanes`). What a road map keeps of it (:class:`csws.road.network.NetLanes`) is a
few megabytes of plain values, so it is written beside the fitted profiles (:func:`csws.curvature.profile_cache_dir`,
``CSWS_CACHE_DIR``) and read back on the next load of the same file:

* the file is named by a digest of the network file's bytes and of the reader (the modules that read a network,
  :mod:`csws.road.network` and :mod:`csws.road.continuations`, this one, and the versions of sumolib and numpy),
  so that a changed network or a changed reader is read afresh, never taken from an old file; a network file
  that changes while it is parsed is not kept;
* a file that is missing, unreadable or not a whole file of this module's is read past: the network is parsed
  and the file written again, atomically; a folder that cannot be written to only loses the cache;
* the files of other readers are removed when one is written, and of one reader's files the
  :data:`KEPT_NETWORKS` most recently used are kept;
* the lanes read back share their strings and vehicle-class sets as parsed ones do, so a map loaded from the
  cache holds no more memory than one parsed.
"""

from __future__ import annotations

import hashlib
import os
import sys
from functools import cache
from pathlib import Path

import msgspec
import numpy as np
import sumolib

from csws.files import prune_cache, replace_file
from csws.road import continuations, network
from csws.road.network import Lane, NetLanes, NetworkError, net_lanes, projection_net, read_sumo_net

__all__ = ["KEPT_NETWORKS", "read_net_lanes"]

#: The files of this many networks are kept, the most recently used.
KEPT_NETWORKS = 16
#: A temporary file left this long by a writer that never finished is removed, s.
_ABANDONED_S = 3600.0

#: A lane as the file keeps it: :class:`Lane`'s fields in order, its vehicle classes as an index into the
#: distinct sets of the network.
_StoredLane = tuple[str, str, int, str, str, str, float, float, float, int, bool, bool, str]


class _Stored(msgspec.Struct, array_like=True, frozen=True):
    """:class:`NetLanes` as the file keeps it: the shapes as raw float64 and int64 bytes, the location's attributes."""

    lanes: list[_StoredLane]
    vclass_sets: list[list[str]]
    xy: bytes
    vertex_start: bytes
    successors: list[list[int]]
    location: dict[str, str]


_DECODER = msgspec.msgpack.Decoder(_Stored)
_ENCODER = msgspec.msgpack.Encoder()


def read_net_lanes(net_path: str | Path, cache_dir: Path | None) -> NetLanes:
    """What a road map keeps of the SUMO network at ``net_path``: read from ``cache_dir`` where this network was
    read before by the same reader, else parsed (and kept there; ``cache_dir`` None parses it every time).

    Raises
    ------
    NetworkError
        If the file is missing, is not a SUMO network, or has no lanes (parsed, never kept).
    """
    path = Path(net_path)
    if cache_dir is None:
        return _parsed(path)
    digest = _file_digest(path)
    if digest is None:
        return _parsed(path)  # read_sumo_net says what is wrong with it
    reader = _reader_digest()
    kept = Path(cache_dir) / f"lanes-{reader}-{digest}.msgpack"
    lanes = _read(kept)
    if lanes is None:
        lanes = _parsed(path)
        if _file_digest(path) == digest:  # the file parsed is the one named
            _write(kept, lanes, reader)
    return lanes


def _parsed(path: Path) -> NetLanes:
    """The network at ``path`` parsed by sumolib and copied into :class:`NetLanes` (a network without lanes, or
    with a broken shape, named in the error)."""
    net = read_sumo_net(path)
    try:
        return net_lanes(net)
    except NetworkError as error:
        raise NetworkError(f"{path.name}: {error}") from None


def _file_digest(path: Path) -> str | None:
    """Digest of a file's bytes, None where it cannot be read."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:32]
    except OSError:
        return None


@cache
def _reader_digest() -> str:
    """Digest of what reads a network: the source of the modules that do, and the versions of sumolib and numpy
    (sumolib's reader module itself where it carries no version)."""
    digest = hashlib.sha256(np.__version__.encode())
    version = getattr(sumolib, "__version__", None)
    digest.update(str(version).encode() if version else Path(str(sumolib.net.__file__)).read_bytes())
    for module in (network, continuations, sys.modules[__name__]):
        digest.update(Path(str(module.__file__)).read_bytes())
    return digest.hexdigest()[:16]


def _read(path: Path) -> NetLanes | None:
    """The lanes kept in ``path``, None where it is missing or not a whole file of this module's."""
    try:
        stored = _DECODER.decode(path.read_bytes())
        xy = np.frombuffer(stored.xy, dtype=np.float64).reshape(-1, 2)
        vertex_start = np.frombuffer(stored.vertex_start, dtype=np.int64)
    except (OSError, ValueError, msgspec.MsgspecError):
        return None
    if not _whole(stored, xy, vertex_start):
        return None
    try:
        os.utime(path)  # most recently used: kept when older ones are removed
    except OSError:
        pass
    return NetLanes(_lanes(stored), xy.copy(), vertex_start.copy(), stored.successors, projection_net(stored.location))


def _whole(stored: _Stored, xy: np.ndarray, vertex_start: np.ndarray) -> bool:
    """Whether a decoded file holds a network as :func:`net_lanes` makes one: lanes of two vertices or more laid
    end to end, successors and vehicle-class sets that are lanes and sets of it."""
    count = len(stored.lanes)
    if count == 0 or len(vertex_start) != count + 1 or len(stored.successors) != count:
        return False
    if vertex_start[0] != 0 or vertex_start[-1] != len(xy) or np.any(np.diff(vertex_start) < 2):
        return False
    following = [index for row in stored.successors for index in row]
    sets = [lane[9] for lane in stored.lanes]
    in_range = not following or 0 <= min(following) <= max(following) < count
    return in_range and 0 <= min(sets) <= max(sets) < len(stored.vclass_sets)


def _lanes(stored: _Stored) -> list[Lane]:
    """The lanes of a decoded file, their strings interned and their vehicle-class sets shared, as parsed lanes
    share them (one string or set object for each distinct value, not one a lane)."""
    vclass_sets = [frozenset(sys.intern(vclass) for vclass in vclasses) for vclasses in stored.vclass_sets]
    intern = sys.intern
    return [
        Lane(
            intern(lane_id),
            intern(edge_id),
            index,
            intern(function),
            intern(street_name),
            intern(road_type),
            speed_limit_mps,
            length_m,
            shape_length_m,
            vclass_sets[vclass_set],
            in_roundabout,
            continues_road,
            intern(continues_into),
        )
        for (
            lane_id,
            edge_id,
            index,
            function,
            street_name,
            road_type,
            speed_limit_mps,
            length_m,
            shape_length_m,
            vclass_set,
            in_roundabout,
            continues_road,
            continues_into,
        ) in stored.lanes
    ]


def _stored(lanes: NetLanes) -> _Stored:
    """:class:`NetLanes` as the file keeps it."""
    set_index: dict[frozenset[str], int] = {}
    for lane in lanes.lanes:
        set_index.setdefault(lane.allowed_vclasses, len(set_index))
    return _Stored(
        [
            (
                lane.lane_id,
                lane.edge_id,
                lane.index,
                lane.function,
                lane.street_name,
                lane.road_type,
                lane.speed_limit_mps,
                lane.length_m,
                lane.shape_length_m,
                set_index[lane.allowed_vclasses],
                lane.in_roundabout,
                lane.continues_road,
                lane.continues_into,
            )
            for lane in lanes.lanes
        ],
        [sorted(vclasses) for vclasses in set_index],
        np.ascontiguousarray(lanes.xy, dtype=np.float64).tobytes(),
        np.ascontiguousarray(lanes.vertex_start, dtype=np.int64).tobytes(),
        [list(following) for following in lanes.successors],
        dict(getattr(lanes.geo, "_location", {})),
    )


def _write(path: Path, lanes: NetLanes, reader: str) -> None:
    """Write ``lanes`` to ``path`` atomically, then remove the files of other readers than ``reader`` and all but
    the :data:`KEPT_NETWORKS` most recently used of its own."""
    content = _ENCODER.encode(_stored(lanes))
    try:
        replace_file(path, lambda file: file.write(content), ".lanes-", ".msgpack")
    except OSError:
        return
    prune_cache(path.parent, "lanes", ".msgpack", reader, KEPT_NETWORKS, _ABANDONED_S)
