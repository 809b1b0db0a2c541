"""Each lane's lateral offset from its reference lane is measured once and read back to the bit.

Truth is the geometry built here: a reference lane along a bend, a lane beside it drawn 3.2 m to its left
(offset +3.2 m) and one 3.2 m to its right, and a lane that leaves the road (not parallel: no offset).
Every offset read from the cache is the float :func:`csws.road.sharing.lateral_offsets_m` measures, and a
bundled network of lanes side by side (the fleet road of four lanes each way) loads the same road map with
the cache as without it.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import pytest

from csws.geometry import arc, sample_pieces, straight
from csws.networks.fleet import build_fleet_net
from csws.road import offsets_cache, sharing
from csws.road.roadmap import RoadMap

#: The lanes' distance apart, m.
LANE_WIDTH_M = 3.2


def _lanes() -> tuple[list[np.ndarray], np.ndarray]:
    """A reference lane along a straight and an R 150 m bend, the lanes 3.2 m to its left and right, and a lane
    that leaves it; every lane's reference is the first."""
    xy, _ = sample_pieces([straight(100.0), arc(150.0, 120.0, "left"), straight(100.0)], 1.0, (0.0, 0.0), 0.0)
    heading = np.arctan2(*np.gradient(xy, axis=0)[:, ::-1].T)
    left = np.stack((-np.sin(heading), np.cos(heading)), axis=1)
    leaving = np.column_stack((xy[:, 0], np.linspace(0.0, 40.0, len(xy))))
    shapes = [xy, xy + LANE_WIDTH_M * left, xy - LANE_WIDTH_M * left, leaving]
    return shapes, np.zeros(len(shapes), dtype=np.int64)


def _not_measured(*args):
    raise AssertionError("measured again")


def test_offsets_are_measured_once_and_read_back_to_the_bit(tmp_path: Path, monkeypatch) -> None:
    shapes, reference = _lanes()
    first = offsets_cache.cached_lateral_offsets_m(shapes, reference, tmp_path)
    assert first[0] == 0.0 and math.isnan(first[3])
    assert first[1:3] == pytest.approx([LANE_WIDTH_M, -LANE_WIDTH_M], abs=0.01)
    np.testing.assert_array_equal(first, sharing.lateral_offsets_m(shapes, reference))
    assert len(list(tmp_path.glob("offsets-*.npy"))) == 1

    monkeypatch.setattr(sharing, "lateral_offsets_m", _not_measured)
    np.testing.assert_array_equal(offsets_cache.cached_lateral_offsets_m(shapes, reference, tmp_path), first)


def test_moved_lanes_a_broken_file_and_no_folder_are_measured_anew(tmp_path: Path) -> None:
    shapes, reference = _lanes()
    offsets_cache.cached_lateral_offsets_m(shapes, reference, tmp_path)
    moved = [shapes[0], shapes[0] + 2.0 * (shapes[1] - shapes[0]), *shapes[2:]]
    moved_m = offsets_cache.cached_lateral_offsets_m(moved, reference, tmp_path)[1]
    assert moved_m == pytest.approx(2 * LANE_WIDTH_M, abs=0.01)
    kept = list(tmp_path.glob("offsets-*.npy"))
    kept[0].write_bytes(b"not numpy")
    np.savez(kept[1], offsets=np.zeros(4))  # a zip of arrays under the name
    np.testing.assert_array_equal(
        offsets_cache.cached_lateral_offsets_m(shapes, reference, tmp_path),
        sharing.lateral_offsets_m(shapes, reference),
    )
    unwritable = tmp_path / "a-file"
    unwritable.write_text("", encoding="utf-8")
    np.testing.assert_array_equal(
        offsets_cache.cached_lateral_offsets_m(shapes, reference, unwritable / "cache"),
        sharing.lateral_offsets_m(shapes, reference),
    )


def test_files_of_other_code_are_removed_and_few_maps_are_kept(tmp_path: Path) -> None:
    foreign = tmp_path / "offsets-0000000000000000-00.npy"
    np.save(foreign, np.zeros(2))
    abandoned, writing = tmp_path / ".offsets-abandoned.npy", tmp_path / ".offsets-writing.npy"
    others = [tmp_path / "profiles-0-0.npz", tmp_path / "lanes-0-0.msgpack", abandoned, writing]
    for path in others:
        path.write_bytes(b"")
    os.utime(abandoned, (time.time() - 2 * 3600, time.time() - 2 * 3600))
    shapes, reference = _lanes()
    written = []
    for shift_m in range(offsets_cache.KEPT_MAPS + 2):
        offsets_cache.cached_lateral_offsets_m([shape + shift_m for shape in shapes], reference, tmp_path)
        (latest,) = set(tmp_path.glob("offsets-*.npy")) - set(written) - {foreign}
        written.append(latest)
        os.utime(latest, (time.time() - 1000 + shift_m, time.time() - 1000 + shift_m))  # written in this order
    assert not foreign.exists() and not abandoned.exists()
    assert all(path.exists() for path in others if path is not abandoned)  # other caches' files, a file being written
    assert sorted(tmp_path.glob("offsets-*.npy")) == sorted(written[-offsets_cache.KEPT_MAPS :])


@pytest.mark.sumo
def test_lanes_side_by_side_load_the_same_road_map_with_the_cache_as_without(tmp_path: Path, monkeypatch) -> None:
    net = build_fleet_net(tmp_path / "fleet4.net.xml", lanes=4)
    monkeypatch.setenv("CSWS_CACHE_DIR", str(tmp_path / "cache"))
    measured = RoadMap.load(net, cache=False)
    RoadMap.load(net)
    assert len(list((tmp_path / "cache").glob("offsets-*.npy"))) == 1
    monkeypatch.setattr(sharing, "lateral_offsets_m", _not_measured)
    read = RoadMap.load(net)
    for ours, theirs in zip(read.chains.runs, measured.chains.runs, strict=True):
        for run, truth in zip(ours, theirs, strict=True):
            np.testing.assert_array_equal(run.offset_m, truth.offset_m)
    assert [(c.lane_id, c.curve) for c in read.curves()] == [(c.lane_id, c.curve) for c in measured.curves()]
