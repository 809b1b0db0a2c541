"""Every bundled network built, or checked against a fresh build (``csws networks build [--check]``).

The standard's tracks (:mod:`csws.networks.generate`) go in the folder itself, the real-road
tracks (:mod:`csws.networks.real_roads`) in its ``real_roads`` folder, the forward collision
warning's (:mod:`csws.networks.fcw_tracks`) in its ``fcw`` folder.
"""

from __future__ import annotations

from pathlib import Path

from .fcw_tracks import FCW_DIR, build_fcw_tracks, compare_fcw_tracks
from .generate import build_tracks, compare_tracks
from .real_roads import REAL_ROADS_DIR, build_real_roads, compare_real_roads

__all__ = ["build_networks", "compare_networks"]


def build_networks(directory: Path) -> list[Path]:
    """Build every bundled network into ``directory`` with its ground truth; the network paths."""
    return (
        build_tracks(directory)
        + build_real_roads(Path(directory) / REAL_ROADS_DIR)
        + build_fcw_tracks(Path(directory) / FCW_DIR)
    )


def compare_networks(directory: Path) -> list[str]:
    """Rebuild every bundled network and list how ``directory`` differs; empty when it matches."""
    return (
        compare_tracks(directory)
        + compare_real_roads(Path(directory) / REAL_ROADS_DIR)
        + compare_fcw_tracks(Path(directory) / FCW_DIR)
    )
