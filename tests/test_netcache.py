"""A network read once loads from the cache as the same road map, and a changed or broken file is read afresh.

Truth is the network parsed by sumolib with the cache off (``RoadMap.load(..., cache=False)``): the road map
loaded through the kept lanes has the same lanes, shapes, successors, location and curves to the bit.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from csws.networks import networks_dir
from csws.road import netcache
from csws.road.network import NetworkError
from csws.road.roadmap import RoadMap

NETWORKS = ["t7_left.net.xml", "real_roads/rr_side_road.net.xml", "real_roads/rr_node_in_curve.net.xml"]


@pytest.fixture
def cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("CSWS_CACHE_DIR", str(folder))
    return folder


def _kept(cache_dir: Path) -> list[Path]:
    return sorted(cache_dir.glob("lanes-*.msgpack"))


def _assert_same(loaded: RoadMap, parsed: RoadMap) -> None:
    assert loaded.lane_ids == parsed.lane_ids
    assert all(loaded.lane(lane_id) == parsed.lane(lane_id) for lane_id in parsed.lane_ids)
    assert all(loaded.successors(lane_id) == parsed.successors(lane_id) for lane_id in parsed.lane_ids)
    assert all(np.array_equal(loaded.lane_shape(lane_id), parsed.lane_shape(lane_id)) for lane_id in parsed.lane_ids)
    assert loaded.geo._location == parsed.geo._location
    assert [(c.lane_id, c.curve) for c in loaded.curves()] == [(c.lane_id, c.curve) for c in parsed.curves()]


@pytest.mark.parametrize("name", NETWORKS)
def test_a_network_loaded_again_comes_from_the_cache_as_the_same_road_map(cache_dir: Path, name: str) -> None:
    path = networks_dir() / name
    first = RoadMap.load(path)
    kept = _kept(cache_dir)
    assert len(kept) == 1
    written = kept[0].read_bytes()
    again = RoadMap.load(path)
    assert _kept(cache_dir) == kept and kept[0].read_bytes() == written  # read, not written again
    parsed = RoadMap.load(path, cache=False)
    _assert_same(first, parsed)
    _assert_same(again, parsed)


def test_a_changed_network_file_is_read_afresh(cache_dir: Path, tmp_path: Path) -> None:
    path = tmp_path / "road.net.xml"
    shutil.copy(networks_dir() / "t7_left.net.xml", path)
    before = RoadMap.load(path)
    assert all(before.lane(lane_id).speed_limit_mps == 50.0 for lane_id in before.lane_ids)
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace('speed="50.000"', 'speed="7.000"'), encoding="utf-8")
    after = RoadMap.load(path)
    assert all(after.lane(lane_id).speed_limit_mps == 7.0 for lane_id in after.lane_ids)
    _assert_same(after, RoadMap.load(path, cache=False))
    assert len(_kept(cache_dir)) == 2


@pytest.mark.parametrize("damage", ["truncated", "empty", "other bytes"])
def test_a_broken_kept_file_is_read_past_and_written_again(cache_dir: Path, damage: str) -> None:
    path = networks_dir() / "t7_left.net.xml"
    RoadMap.load(path)
    (kept,) = _kept(cache_dir)
    whole = kept.read_bytes()
    kept.write_bytes({"truncated": whole[: len(whole) // 2], "empty": b"", "other bytes": b"\x93\x01\x02\x03"}[damage])
    _assert_same(RoadMap.load(path), RoadMap.load(path, cache=False))
    assert kept.read_bytes() == whole


def test_nothing_is_kept_with_the_cache_off(cache_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    RoadMap.load(networks_dir() / "t7_left.net.xml", cache=False)
    monkeypatch.setenv("CSWS_CACHE_DIR", "")
    RoadMap.load(networks_dir() / "t7_left.net.xml")
    assert not cache_dir.exists() or not _kept(cache_dir)


def test_a_missing_network_is_the_same_error_with_the_cache_on_or_off(cache_dir: Path, tmp_path: Path) -> None:
    missing = tmp_path / "none.net.xml"
    with pytest.raises(NetworkError) as cached:
        RoadMap.load(missing)
    with pytest.raises(NetworkError) as parsed:
        RoadMap.load(missing, cache=False)
    assert str(cached.value) == str(parsed.value) and str(missing) in str(cached.value)
    assert not _kept(cache_dir)


def test_the_most_recently_used_networks_are_kept(
    cache_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(netcache, "KEPT_NETWORKS", 2)
    paths = []
    for name in NETWORKS:
        paths.append(tmp_path / Path(name).name)
        shutil.copy(networks_dir() / name, paths[-1])
    RoadMap.load(paths[0])
    RoadMap.load(paths[1])
    RoadMap.load(paths[0])  # used again: more recent than the second
    RoadMap.load(paths[2])
    kept = _kept(cache_dir)
    assert len(kept) == 2
    RoadMap.load(paths[0])
    assert _kept(cache_dir) == kept  # the first is still kept: read, nothing written


def test_a_network_file_changed_while_it_is_parsed_is_not_kept(
    cache_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "road.net.xml"
    shutil.copy(networks_dir() / "t7_left.net.xml", path)
    parse = netcache.read_sumo_net

    def parse_after_a_rewrite(net_path: Path):
        text = path.read_text(encoding="utf-8")
        path.write_text(text.replace('speed="50.000"', 'speed="7.000"'), encoding="utf-8")
        return parse(net_path)

    monkeypatch.setattr(netcache, "read_sumo_net", parse_after_a_rewrite)
    RoadMap.load(path)
    assert not _kept(cache_dir)


def test_a_kept_file_that_cannot_be_removed_does_not_fail_a_load(cache_dir: Path) -> None:
    (cache_dir / "lanes-0000000000000000-aaaa.msgpack").mkdir(parents=True)  # another reader's, not a file
    _assert_same(RoadMap.load(networks_dir() / "t7_left.net.xml"), RoadMap.load(networks_dir() / "t7_left.net.xml"))


def test_lanes_read_back_share_their_vehicle_class_sets_as_parsed_ones_do(cache_dir: Path) -> None:
    path = networks_dir() / "real_roads/rr_side_road.net.xml"
    RoadMap.load(path)
    loaded = RoadMap.load(path)
    sets = [loaded.lane(lane_id).allowed_vclasses for lane_id in loaded.lane_ids]
    assert len({id(vclasses) for vclasses in sets}) == len(set(sets))
