"""Keeps each lane's lateral offset from its edge's reference lane on disk, so that a road map measures them once.

A road map loaded from the profile cache still measured every lane against its reference lane
(:func:`csws.road.sharing.lateral_offsets_m`): on the fleet road of four lanes each way, 78 lanes of some 730
points each, 0.18 s of a 0.24 s load, at every load. The offsets are a function of the lanes' shapes and
their reference lanes alone, so they are kept beside the fitted profiles (:func:`csws.curvature.profile_cache_dir`)
in a file named by two digests:

* the code's: the source of :mod:`csws.road.sharing` (which measures them) and of this module, and the versions
  of numpy and shapely (whose spatial index picks the segments measured), so that a changed measure is never
  read from an older file;
* the data's: every coordinate of every lane's shape, in order, and every lane's reference lane.

A file that is missing, unreadable or not one offset per lane is measured anew and written again, atomically; a
folder that cannot be written to only loses the cache. Files of other code are removed when one is written, and
of this code's the :data:`KEPT_MAPS` most recently used are kept. An offset read back is the same float as one
measured (``.npy`` keeps every bit).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np
import shapely

from csws.curvature.cache import polylines_digest
from csws.files import prune_cache, replace_file
from csws.road import sharing

__all__ = ["KEPT_MAPS", "cached_lateral_offsets_m"]

#: The offsets of this many maps are kept, the most recently used.
KEPT_MAPS = 16
#: A temporary file older than this, s, was abandoned by a writer that stopped.
_ABANDONED_S = 3600.0


def cached_lateral_offsets_m(
    road_shapes: Sequence[np.ndarray], reference: np.ndarray, cache_dir: Path | None
) -> np.ndarray:
    """Each lane's lateral offset from its reference lane, m, as :func:`csws.road.sharing.lateral_offsets_m`
    measures it: read from ``cache_dir`` where these lanes were measured before, else measured and kept there
    (``None``: measured without a cache)."""
    if cache_dir is None:
        return sharing.lateral_offsets_m(road_shapes, reference)
    code = _code_digest()
    path = Path(cache_dir) / f"offsets-{code}-{_data_digest(road_shapes, reference)}.npy"
    offsets = _read(path, len(road_shapes))
    if offsets is None:
        offsets = sharing.lateral_offsets_m(road_shapes, reference)
        _write(path, offsets, code)
    return offsets


@cache
def _code_digest() -> str:
    """Digest of the code that measures the offsets: :mod:`csws.road.sharing`, this module, numpy and shapely."""
    digest = hashlib.sha256(f"numpy {np.__version__} shapely {shapely.__version__}".encode())
    for source in (Path(sharing.__file__), Path(__file__)):
        digest.update(source.read_bytes())
    return digest.hexdigest()[:16]


def _data_digest(road_shapes: Sequence[np.ndarray], reference: np.ndarray) -> str:
    """Digest of the lanes: their shapes (:func:`csws.curvature.cache.polylines_digest`) and reference lanes."""
    digest = hashlib.sha256(polylines_digest(road_shapes).encode())
    digest.update(np.ascontiguousarray(reference, dtype=np.int64).tobytes())
    return digest.hexdigest()[:32]


def _read(path: Path, lane_count: int) -> np.ndarray | None:
    """The offsets kept in ``path``, None where it is missing or not one float per lane (another numpy file, a zip
    of them, anything else)."""
    try:
        with path.open("rb") as file:
            offsets = np.load(file, allow_pickle=False)
            if not isinstance(offsets, np.ndarray):
                return None
    except (OSError, ValueError, EOFError):
        return None
    if offsets.dtype != np.float64 or offsets.shape != (lane_count,):
        return None
    try:
        os.utime(path)  # most recently used: kept when older ones are removed
    except OSError:
        pass
    return offsets


def _write(path: Path, offsets: np.ndarray, code: str) -> None:
    """Write ``offsets`` to ``path`` atomically, then prune the folder; a folder that cannot be written to only
    loses the cache."""
    try:
        replace_file(path, lambda file: np.save(file, offsets, allow_pickle=False), ".offsets-", ".npy")
    except OSError:
        return
    prune_cache(path.parent, "offsets", ".npy", code, KEPT_MAPS, _ABANDONED_S)
