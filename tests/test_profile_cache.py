"""The profile cache gives exactly the fit, reads it back without fitting, and never
serves a fit of other polylines, of another road model, or from a broken file."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import csws.curvature.cache as cache_module
from csws.curvature import RadiusProfile, cached_radius_profiles, profile_cache_dir, radius_profiles
from csws.geometry import arc, clothoid, sample_pieces, straight
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap


def _polylines() -> list[np.ndarray]:
    """Roads of every kind the fit meets: dense arcs and clothoids, a sparse noisy way, degenerate lines."""
    rng = np.random.default_rng(91)
    spiral, _ = sample_pieces(
        [
            straight(80),
            clothoid(40, math.inf, 90, "left"),
            arc(90, 40, "left"),
            clothoid(40, 90, math.inf),
            straight(80),
        ],
        0.5,
    )
    compound, _ = sample_pieces([straight(60), arc(200, 20, "right"), arc(45, 70, "right"), straight(60)], 1.0)
    way, _ = sample_pieces([straight(100), arc(120, 60, "left"), straight(100)], 15.0)
    return [
        spiral.round(2),
        compound.round(2),
        way + rng.normal(0.0, 0.5, way.shape),
        np.empty((0, 2)),
        np.array([[3.0, 4.0]]),
        np.array([[0.0, 0.0], [0.0, 0.0], [50.0, 0.0]]),
    ]


def _assert_same(read: list[RadiusProfile], fitted: list[RadiusProfile]) -> None:
    assert len(read) == len(fitted)
    for a, b in zip(read, fitted, strict=False):
        assert a.parts == b.parts
        for name in ("s", "curvature", "radius"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def _no_fit(*_args, **_kwargs):
    raise AssertionError("the cache should have been read, not the polylines fitted")


def test_a_cached_fit_is_the_fit_and_is_read_back_without_fitting(tmp_path: Path, monkeypatch) -> None:
    polylines = _polylines()
    fitted = radius_profiles(polylines)
    _assert_same(cached_radius_profiles(polylines, tmp_path), fitted)
    assert len(list(tmp_path.glob("profiles-*.npz"))) == 1
    monkeypatch.setattr(cache_module, "radius_profiles", _no_fit)
    _assert_same(cached_radius_profiles(polylines, tmp_path), fitted)


def test_other_polylines_are_fitted_not_served_the_file_of_these(tmp_path: Path) -> None:
    polylines = _polylines()
    cached_radius_profiles(polylines, tmp_path)
    moved = [xy.copy() for xy in polylines]
    moved[1][len(moved[1]) // 2] += (0.0, 0.3)
    _assert_same(cached_radius_profiles(moved, tmp_path), radius_profiles(moved))
    _assert_same(cached_radius_profiles(polylines[:2], tmp_path), radius_profiles(polylines[:2]))
    assert len(list(tmp_path.glob("profiles-*.npz"))) == 3


@pytest.mark.parametrize("damage", ["truncated", "not a zip", "empty"])
def test_a_broken_file_is_fitted_again_and_replaced(tmp_path: Path, damage: str) -> None:
    polylines = _polylines()
    cached_radius_profiles(polylines, tmp_path)
    [path] = tmp_path.glob("profiles-*.npz")
    content = path.read_bytes()
    path.write_bytes({"truncated": content[: len(content) // 2], "not a zip": b"profiles", "empty": b""}[damage])
    _assert_same(cached_radius_profiles(polylines, tmp_path), radius_profiles(polylines))
    assert path.read_bytes() == content


def test_files_of_another_road_model_are_never_read_and_are_removed(tmp_path: Path, monkeypatch) -> None:
    polylines = _polylines()
    cached_radius_profiles(polylines, tmp_path)
    [old] = tmp_path.glob("profiles-*.npz")
    monkeypatch.setattr(cache_module, "_model_digest", lambda: "a-changed-model")
    calls = []
    monkeypatch.setattr(cache_module, "radius_profiles", lambda points: calls.append(1) or radius_profiles(points))
    cached_radius_profiles(polylines, tmp_path)
    assert calls == [1]
    assert not old.exists()
    assert [path.name.startswith("profiles-a-changed-model-") for path in tmp_path.glob("profiles-*.npz")] == [True]


def test_a_file_of_another_road_model_that_cannot_be_removed_does_not_fail_the_fit(tmp_path: Path) -> None:
    (tmp_path / "profiles-another-model-0000.npz").mkdir()  # not a file: unlink refuses it
    _assert_same(cached_radius_profiles(_polylines(), tmp_path), radius_profiles(_polylines()))


def test_a_folder_that_cannot_be_written_only_costs_the_fit(tmp_path: Path) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    _assert_same(cached_radius_profiles(_polylines(), blocked / "cache"), radius_profiles(_polylines()))


def test_the_folder_comes_from_the_environment_and_an_empty_value_turns_it_off(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("CSWS_CACHE_DIR", str(tmp_path))
    assert profile_cache_dir() == tmp_path
    monkeypatch.setenv("CSWS_CACHE_DIR", "")
    assert profile_cache_dir() is None
    monkeypatch.delenv("CSWS_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert profile_cache_dir() == tmp_path / "xdg" / "csws"


def test_a_network_loaded_from_the_cache_has_the_curves_of_a_fresh_fit(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("CSWS_CACHE_DIR", str(tmp_path))
    net = networks_dir() / "t9_m3_n_o_test2_left.net.xml"
    fresh = RoadMap.load(net, cache=False)
    assert not list(tmp_path.iterdir())
    RoadMap.load(net)
    monkeypatch.setattr(cache_module, "radius_profiles", _no_fit)
    cached = RoadMap.load(net)
    assert cached.curves() == fresh.curves()
