"""The exact κ(s) of every SUMO lane netconvert made from an OpenDRIVE file, kept beside the network.

netconvert (``--output.original-names``) tags each lane it builds from an OpenDRIVE lane with
``origId = "<road id>_<lane id>"``; internal junction lanes carry none. A SUMO lane is mapped to the
lane section of that OpenDRIVE lane whose centre line its shape's ends lie on (netconvert may cut a
lane back at a section joint), in the direction SUMO drives it: its shape's first point to its last.
netconvert drives right lanes along s and left lanes against it, also on a road whose ``rule`` is
``LHT`` (which it does not read): such lanes are noted. Its κ(σ) is the lane's between the two ends,
measured from the SUMO lane's first point, with the sign of its turn as driven; grade and cross slope
come with it, in the driving direction.

The file is ``NAME.kappa.json`` beside ``NAME.net.xml[.gz]``.
"""

from __future__ import annotations

import gzip
import json
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from .lanes import LaneTrack, lane_track
from .model import OpenDriveError, Road
from .reader import OpenDriveFile

__all__ = ["ExactLane", "exact_path", "exact_lanes", "write_exact", "read_exact", "PROFILE_STEP_M", "SNAP_M"]

#: Spacing of the grade and superelevation samples kept per lane, m.
PROFILE_STEP_M = 5.0
#: Largest distance from a SUMO lane end to the OpenDRIVE lane centre it is mapped onto, m.
SNAP_M = 0.5
_FORMAT = "csws-opendrive-kappa/1"


@dataclass(frozen=True)
class ExactLane:
    """The exact curvature of one SUMO lane.

    Attributes
    ----------
    road_id, section_s, opendrive_lane, along_s
        Its OpenDRIVE road, lane section start, lane id and whether it is driven along s.
    start_road_s, end_road_s
        The road positions s of its first and last points.
    length_m
        Its exact centre-line length between its SUMO ends, m.
    bounds, start_curvature, end_curvature
        κ(σ) as linear parts: bounds in σ from its first point ``(m + 1,)``, signed curvature
        (positive turning left as driven) at each part's start and end ``(m,)``.
    profile_s, grade_pct, superelevation_pct
        Samples along σ of the grade (rising positive) and the cross slope (falling to the
        driver's right positive), in per cent.
    """

    road_id: str
    section_s: float
    opendrive_lane: int
    along_s: bool
    start_road_s: float
    end_road_s: float
    length_m: float
    bounds: np.ndarray
    start_curvature: np.ndarray
    end_curvature: np.ndarray
    profile_s: np.ndarray
    grade_pct: np.ndarray
    superelevation_pct: np.ndarray


def exact_path(net_path: str | Path) -> Path:
    """Where the exact curvature of network ``net_path`` is kept: ``NAME.kappa.json`` beside it."""
    net_path = Path(net_path)
    name = net_path.name
    for suffix in (".net.xml.gz", ".net.xml", ".xml.gz", ".xml"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
            break
    return net_path.with_name(name + ".kappa.json")


def _sumo_lanes(net_path: Path) -> list[tuple[str, str, np.ndarray]]:
    """(SUMO lane id, origId, shape) of every lane that netconvert tagged with an OpenDRIVE origin."""
    opener = gzip.open if net_path.name.endswith(".gz") else open
    with opener(net_path, "rb") as file:
        root = ElementTree.parse(file).getroot()
    lanes = []
    for lane in root.iter("lane"):
        origin = next((p.get("value") for p in lane.findall("param") if p.get("key") == "origId"), None)
        if origin and lane.get("shape"):
            shape = np.array([[float(v) for v in point.split(",")[:2]] for point in lane.get("shape", "").split()])
            lanes.append((lane.get("id", ""), origin, shape))
    return lanes


def _snap(track: LaneTrack, point: np.ndarray) -> tuple[float, float]:
    """Arc length along a lane track of the point nearest ``point`` and its distance, m."""
    xy = np.column_stack((track.x, track.y))
    segment = np.diff(xy, axis=0)
    length2 = np.maximum(np.einsum("ij,ij->i", segment, segment), 1e-18)
    fraction = np.clip(np.einsum("ij,ij->i", point - xy[:-1], segment) / length2, 0.0, 1.0)
    foot = xy[:-1] + fraction[:, None] * segment
    distance = np.hypot(*(foot - point).T)
    best = int(np.argmin(distance))
    return float(track.sigma[best] + fraction[best] * (track.sigma[best + 1] - track.sigma[best])), float(
        distance[best]
    )


def _cut(track: LaneTrack, first: float, last: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a track between σ ``first`` < ``last``, σ measured from ``first``."""
    inner = track.bounds[(track.bounds > first) & (track.bounds < last)]
    bounds = np.concatenate(([first], inner, [last]))
    part = np.clip(np.searchsorted(track.bounds, 0.5 * (bounds[:-1] + bounds[1:])) - 1, 0, len(track.bounds) - 2)
    span = track.bounds[part + 1] - track.bounds[part]

    def at(sigma: np.ndarray) -> np.ndarray:
        fraction = np.divide(sigma - track.bounds[part], span, out=np.zeros(len(part)), where=span > 0)
        return track.start_curvature[part] + (track.end_curvature[part] - track.start_curvature[part]) * fraction

    return bounds - first, at(bounds[:-1]), at(bounds[1:])


def _mapped(road: Road, track: LaneTrack, shape: np.ndarray, lane_id: int) -> ExactLane:
    """One SUMO lane's exact curvature from the track its ends lie on, in the direction SUMO drives it (its shape's:
    as the road's traffic rule says for a network netconvert built from the file)."""
    first, _ = _snap(track, shape[0])
    last, _ = _snap(track, shape[-1])
    along = first <= last
    if not along:
        first, last = last, first
    bounds, k0, k1 = _cut(track, first, last)
    length = float(bounds[-1])
    sigma = np.linspace(first, last, max(int(np.ceil(length / PROFILE_STEP_M)), 1) + 1)
    s = np.interp(sigma, track.sigma, track.s)
    grade = np.array([100.0 * (r.slope(v) if (r := road.elevation(v)) else 0.0) for v in s.tolist()])
    roll = np.array([np.tan(r.value(v)) * 100.0 if (r := road.superelevation(v)) else 0.0 for v in s.tolist()])
    if not along:
        bounds, k0, k1 = length - bounds[::-1], -k1[::-1], -k0[::-1]
        sigma, s, grade, roll = sigma[::-1], s[::-1], -grade[::-1], -roll[::-1]
    return ExactLane(
        road.road_id,
        track.section_s,
        lane_id,
        along,
        float(s[0]),
        float(s[-1]),
        length,
        bounds,
        k0,
        k1,
        np.abs(sigma - sigma[0]),
        grade,
        roll,
    )


def exact_lanes(net_path: str | Path, opendrive: OpenDriveFile) -> tuple[dict[str, ExactLane], list[str]]:
    """The exact curvature of every SUMO lane of ``net_path`` built from an OpenDRIVE lane, with notes on lanes left
    to the fit (no matching road or lane, or ends off the lane's centre by over :data:`SNAP_M`)."""
    roads = {road.road_id: road for road in opendrive.roads}
    exact: dict[str, ExactLane] = {}
    notes: list[str] = []
    tracks: dict[tuple[str, int], list[LaneTrack]] = {}
    for sumo_id, origin, shape in _sumo_lanes(Path(net_path)):
        road_id, _, lane_text = origin.rpartition("_")
        road = roads.get(road_id)
        if road is None or not lane_text.lstrip("-").isdigit():
            notes.append(f"lane {sumo_id}: origin {origin!r} is no road and lane of the OpenDRIVE file; fitted")
            continue
        lane_id = int(lane_text)
        if (road_id, lane_id) not in tracks:
            try:
                tracks[road_id, lane_id] = [lane_track(road, s, lane_id) for s in road.sections if s.lane(lane_id)]
            except OpenDriveError as error:
                tracks[road_id, lane_id] = []
                notes.append(f"lane {sumo_id}: {error}; fitted")
                continue
        candidates = [
            (max(_snap(t, shape[0])[1], _snap(t, shape[-1])[1]), i) for i, t in enumerate(tracks[road_id, lane_id])
        ]
        if not candidates or min(candidates)[0] > SNAP_M:
            notes.append(f"lane {sumo_id}: its ends are off road {road_id} lane {lane_id} by over {SNAP_M} m; fitted")
            continue
        exact[sumo_id] = _mapped(road, tracks[road_id, lane_id][min(candidates)[1]], shape, lane_id)
        if exact[sumo_id].along_s != road.drives_along_s(lane_id):
            notes.append(f"lane {sumo_id}: SUMO drives road {road_id} lane {lane_id} against its traffic rule")
    return exact, notes


def write_exact(path: str | Path, lanes: dict[str, ExactLane]) -> Path:
    """Write the exact curvature of SUMO lanes to ``path`` (JSON)."""
    document = {
        "format": _FORMAT,
        "lanes": {
            lane_id: {
                "road": lane.road_id,
                "section_s": lane.section_s,
                "opendrive_lane": lane.opendrive_lane,
                "along_s": lane.along_s,
                "start_road_s": lane.start_road_s,
                "end_road_s": lane.end_road_s,
                "length_m": lane.length_m,
                **{name: getattr(lane, name).tolist() for name in _ARRAYS},
            }
            for lane_id, lane in lanes.items()
        },
    }
    path = Path(path)
    path.write_text(json.dumps(document, separators=(",", ":")), encoding="utf-8")
    return path


_ARRAYS = ("bounds", "start_curvature", "end_curvature", "profile_s", "grade_pct", "superelevation_pct")


def read_exact(path: str | Path) -> dict[str, ExactLane]:
    """The exact curvature kept in ``path`` by :func:`write_exact`.

    Raises
    ------
    OpenDriveError
        When the file is not one :func:`write_exact` wrote.
    """
    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
        if document.get("format") != _FORMAT:
            raise ValueError("unknown format")
        return {
            lane_id: ExactLane(
                str(entry["road"]),
                float(entry["section_s"]),
                int(entry["opendrive_lane"]),
                bool(entry["along_s"]),
                float(entry["start_road_s"]),
                float(entry["end_road_s"]),
                float(entry["length_m"]),
                *(np.array(entry[name], dtype=float) for name in _ARRAYS),
            )
            for lane_id, entry in document["lanes"].items()
        }
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
        raise OpenDriveError(f"{path} is not a csws exact-curvature file: {error}") from None
