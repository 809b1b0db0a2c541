"""A network's files: JSON written one way, and a fresh build compared with the committed one.

Networks are compared lane by lane (ids, speeds, lengths and shape points within a
tolerance), not byte by byte: netconvert stamps each file with the time it was built. JSON
files (the truth, the indexes) must hold the same content.
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from csws.sumo.netbuild import required_attribute

__all__ = ["write_json", "read_lanes", "lane_differences", "json_difference"]


def write_json(path: Path, content: dict) -> None:
    """Write ``content`` as indented JSON with a final newline."""
    path.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")


def read_lanes(net_file: Path) -> dict[str, tuple[float, float, np.ndarray]]:
    """``lane id -> (length m, speed m/s, (n, 2) shape)`` of every lane of a SUMO network, internal ones too."""
    return {
        required_attribute(lane, "id"): (
            float(required_attribute(lane, "length")),
            float(required_attribute(lane, "speed")),
            np.array([[float(v) for v in point.split(",")[:2]] for point in required_attribute(lane, "shape").split()]),
        )
        for lane in ElementTree.parse(net_file).getroot().iter("lane")
    }


def lane_differences(name: str, built: Path, committed: Path, tolerance_m: float) -> list[str]:
    """How the lanes of two builds of a network differ beyond ``tolerance_m``; empty when they match."""
    new, old = read_lanes(built), read_lanes(committed)
    if new.keys() != old.keys():
        return [f"{name}: lanes differ: built {sorted(new)}, committed {sorted(old)}"]
    differences = []
    for lane_id, (length_m, speed_mps, shape) in new.items():
        old_length_m, old_speed_mps, old_shape = old[lane_id]
        if abs(length_m - old_length_m) > tolerance_m:
            differences.append(f"{name}: lane {lane_id} length {old_length_m} m, rebuilt {length_m} m")
        if speed_mps != old_speed_mps:
            differences.append(f"{name}: lane {lane_id} speed {old_speed_mps} m/s, rebuilt {speed_mps} m/s")
        if shape.shape != old_shape.shape:
            differences.append(f"{name}: lane {lane_id} has {len(old_shape)} shape points, rebuilt {len(shape)}")
        elif np.any(np.hypot(*(shape - old_shape).T) > tolerance_m):
            differences.append(f"{name}: lane {lane_id} shape moved by more than {tolerance_m} m")
    return differences


def json_difference(path_built: Path, path_committed: Path) -> list[str]:
    """A one-line difference when two JSON files do not hold the same content."""
    if not path_committed.is_file():
        return [f"{path_committed.name}: missing"]
    same = json.loads(path_built.read_text("utf-8")) == json.loads(path_committed.read_text("utf-8"))
    return [] if same else [f"{path_committed.name}: differs from the generator's"]
