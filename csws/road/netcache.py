"""Keeps what a road map reads of a SUMO network, so that a network read once loads without being parsed again.

Of Bad Hersfeld's load from the profile cache (some 3.7 s), about 2 s are the network itself: sumolib's parse of
its 12,752 lanes and their connections, then the lanes' records, successors and the road's continuations
(:func:`csws.road.network.net_lanes`). What a road map keeps of it (:class:`csws.road.network.NetLanes`) is a
few megabytes of plain values, so it is written beside the fitted profiles (:func:`csws.curvature.profile_cache_dir`,
``CSWS_CACHE_DIR``) and read back on the next load of the same file:

* the file is named by a digest of the network file's bytes, of the modules that read a network
  (:mod:`csws.road.network`, :mod:`csws.road.continuations`) and of sumolib's version, so that a changed network
  or a changed reader is read afresh, never taken from an old file;
* a file that is missing, unreadable or not what this module writes is read past: the network is parsed
  and the file written again, atomically; a folder that cannot be written to only loses the cache;
* the files of other readers (another digest of the modules) are removed when one is written, and of one
  reader's files the :data:`KEPT_NETWORKS` most recently used are kept.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import tempfile
from functools import cache
from pathlib import Path

import msgspec
import numpy as np

from csws.road import continuations, network
from csws.road.network import Lane, NetLanes, NetworkError, net_lanes, projection_net, read_sumo_net

__all__ = ["KEPT_NETWORKS", "read_net_lanes"]

#: The files of this many networks are kept, the most recently used.
KEPT_NETWORKS = 16


class _Stored(msgspec.Struct, array_like=True, frozen=True):
    """:class:`NetLanes` as the file keeps it: the shapes as raw float64 and int64 bytes, the location's attributes."""

    lanes: list[Lane]
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
    try:
        content = path.read_bytes()
    except OSError:
        return _parsed(path)  # read_sumo_net says what is wrong with it
    reader = _reader_digest()
    kept = Path(cache_dir) / f"lanes-{reader}-{hashlib.sha256(content).hexdigest()[:32]}.msgpack"
    lanes = _read(kept)
    if lanes is None:
        lanes = _parsed(path)
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


@cache
def _reader_digest() -> str:
    """Digest of what reads a network: the source of the modules that do, and sumolib's version."""
    digest = hashlib.sha256(importlib.metadata.version("sumolib").encode())
    for module in (network, continuations):
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
    count = len(stored.lanes)
    if count == 0 or len(vertex_start) != count + 1 or len(stored.successors) != count or vertex_start[-1] != len(xy):
        return None
    try:
        os.utime(path)  # most recently used: kept when older ones are removed
    except OSError:
        pass
    return NetLanes(stored.lanes, xy.copy(), vertex_start.copy(), stored.successors, projection_net(stored.location))


def _write(path: Path, lanes: NetLanes, reader: str) -> None:
    """Write ``lanes`` to ``path`` atomically, then remove the files of other readers than ``reader`` and all but
    the :data:`KEPT_NETWORKS` most recently used of its own."""
    stored = _Stored(
        list(lanes.lanes),
        np.ascontiguousarray(lanes.xy, dtype=np.float64).tobytes(),
        np.ascontiguousarray(lanes.vertex_start, dtype=np.int64).tobytes(),
        [list(following) for following in lanes.successors],
        dict(getattr(lanes.geo, "_location", {})),
    )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".lanes-", suffix=".msgpack")
    except OSError:
        return
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(_ENCODER.encode(stored))
        os.replace(temporary, path)
    except OSError:
        Path(temporary).unlink(missing_ok=True)
        return
    _prune(path.parent, reader)


def _prune(folder: Path, reader: str) -> None:
    """Remove the kept networks of other readers than ``reader``, and all but the most recently used of its own."""
    own = []
    for kept in folder.glob("lanes-*.msgpack"):
        if not kept.name.startswith(f"lanes-{reader}-"):
            kept.unlink(missing_ok=True)
            continue
        try:
            own.append((kept.stat().st_mtime, kept))
        except OSError:
            continue
    for _, old in sorted(own, reverse=True)[KEPT_NETWORKS:]:
        old.unlink(missing_ok=True)
