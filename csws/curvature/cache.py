"""Keeps fitted radius profiles on disk, so that a network is fitted once and not at every load.

Fitting every road chain of a city takes seconds; reading the fitted parts back takes
milliseconds. :func:`cached_radius_profiles` gives exactly what
:func:`csws.curvature.radius_profiles` gives, from a file when one was written for the
same polylines by the same road model.

A cache file is named by two digests:

* the road model's: the source of every module of this package, so that a changed fit
  never reads parts an older fit wrote (and files of older models are removed when a new
  one is written, which keeps the folder to one model's files);
* the data's: every coordinate of every polyline, in order, so that a file belongs to
  its polylines whatever network file, import or path they came from.

The folder is ``$CSWS_CACHE_DIR``, else ``$XDG_CACHE_HOME/csws``, else ``~/.cache/csws``;
``CSWS_CACHE_DIR`` set to an empty string turns the cache off. A file that cannot be read
(truncated, foreign, from another numpy) is fitted anew and written again; a folder that
cannot be written to only costs the next load the fit.
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np

from csws.files import replace_file

from .artefacts import kept_to_polyline
from .chords import _chords, _validated
from .fitting import radius_profiles
from .profile import RadiusProfile, profile_from_parts, straight_profile

__all__ = ["cached_radius_profiles", "polylines_digest", "profile_cache_dir"]

#: Arrays of a cache file: per polyline the offset of its first part, and per part its
#: start and end arc length (m) and its signed curvature at start and end (1/m).
_FIELDS = ("part_offset", "start_s", "end_s", "curvature", "end_curvature")


def profile_cache_dir() -> Path | None:
    """The folder fitted profiles are kept in, ``None`` when the cache is turned off."""
    configured = os.environ.get("CSWS_CACHE_DIR")
    if configured is not None:
        return Path(configured).expanduser() if configured.strip() else None
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "csws"


@cache
def _model_digest() -> str:
    """Digest of the road model: the source of every module of this package."""
    digest = hashlib.sha256()
    for source in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(source.name.encode())
        digest.update(source.read_bytes())
    return digest.hexdigest()[:16]


def polylines_digest(points: Sequence[np.ndarray]) -> str:
    """Digest of polylines: their vertex counts and every coordinate, in order (a cache file's data digest)."""
    digest = hashlib.sha256(np.array([len(p) for p in points], dtype=np.int64).tobytes())
    for xy in points:
        digest.update(np.ascontiguousarray(xy, dtype=np.float64).tobytes())
    return digest.hexdigest()[:32]


def cached_radius_profiles(
    polylines: Sequence[np.ndarray], cache_dir: Path | None, *, kept_to_polylines: bool = False
) -> list[RadiusProfile]:
    """The radius profiles of ``polylines`` (:func:`csws.curvature.radius_profiles`), read from
    ``cache_dir`` when they were fitted before, else fitted and written there.

    Parameters
    ----------
    polylines
        ``(n, 2)`` arrays of vertex coordinates, m.
    cache_dir
        The cache folder (see :func:`profile_cache_dir`); ``None`` fits without a cache.
    kept_to_polylines
        Each profile kept to its polyline's net turn and corners
        (:func:`csws.curvature.artefacts.kept_to_polyline`) before it is kept on disk, in files of their own.

    Raises
    ------
    ValueError
        As :func:`csws.curvature.radius_profiles`, for a polyline that is not ``(n, 2)``
        or has non-finite coordinates.
    """
    points = [_validated(xy, i) for i, xy in enumerate(polylines)]

    def fitted() -> list[RadiusProfile]:
        profiles = radius_profiles(points)
        return (
            [kept_to_polyline(xy, p) for xy, p in zip(points, profiles, strict=True)] if kept_to_polylines else profiles
        )

    if cache_dir is None or not points:
        return fitted()
    model = _model_digest()
    kind = "-kept" if kept_to_polylines else ""
    path = Path(cache_dir) / f"profiles-{model}-{polylines_digest(points)}{kind}.npz"
    profiles = _read(path, points)
    if profiles is None:
        profiles = fitted()
        _write(path, profiles, model)
    return profiles


def _read(path: Path, points: Sequence[np.ndarray]) -> list[RadiusProfile] | None:
    """The profiles kept in ``path``, ``None`` when it is missing or does not fit ``points``."""
    try:
        with np.load(path, allow_pickle=False) as stored:
            offset, start_s, end_s, curvature, end_curvature = (stored[name] for name in _FIELDS)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    part_count = len(start_s)
    if (
        len(offset) != len(points) + 1
        or offset[0] != 0
        or offset[-1] != part_count
        or np.any(np.diff(offset) < 0)
        or not len(end_s) == len(curvature) == len(end_curvature) == part_count
    ):
        return None
    chords = _chords(points)
    profiles = []
    for polyline, (first, stop) in enumerate(zip(offset[:-1].tolist(), offset[1:].tolist(), strict=False)):
        vertex_s = chords.vertex_s[chords.polyline_first_vertex[polyline] : chords.polyline_first_vertex[polyline + 1]]
        if first == stop:
            profiles.append(straight_profile(vertex_s))
            continue
        bounds = np.append(start_s[first:stop], end_s[stop - 1])
        profiles.append(profile_from_parts(vertex_s, bounds, curvature[first:stop], end_curvature[first:stop]))
    return profiles


def _write(path: Path, profiles: Sequence[RadiusProfile], model: str) -> None:
    """Write ``profiles`` to ``path`` atomically, then remove the files of other road models
    than ``model`` beside it; a folder that cannot be written to only loses the cache."""
    parts = [part for profile in profiles for part in profile.parts]
    arrays = {
        "part_offset": np.concatenate(([0], np.cumsum([len(profile.parts) for profile in profiles]))).astype(np.int64),
        "start_s": np.array([part.start_s for part in parts], dtype=float),
        "end_s": np.array([part.end_s for part in parts], dtype=float),
        "curvature": np.array([part.curvature for part in parts], dtype=float),
        "end_curvature": np.array([part.final_curvature for part in parts], dtype=float),
    }
    try:
        replace_file(path, lambda file: np.savez(file, **arrays), ".profiles-", ".npz")  # type: ignore[arg-type]
    except OSError:
        return
    for old in path.parent.glob("profiles-*.npz"):
        if not old.name.startswith(f"profiles-{model}-"):
            try:
                old.unlink(missing_ok=True)
            except OSError:  # another user's, or a read-only folder: it stays, the cache still works
                continue
