"""A turn in a cluster of junctions: OpenStreetMap imports make several SUMO junctions, metres apart, of one
crossing, and a fix near the turn of one of them is as near the connections of the next. Bad Hersfeld's crossing
of Kolpingstraße (junctions 2103110964, 2103110979 and 2103110982, within 15 m) has a left turn into street
240545278, whose curve is a level-2 warning at 30 km/h. Vehicles driving straight through the cluster are fed
fixes with σ 3 m noise at 1 Hz (seeded drives: the truth is each drive's own path). A fix is matched onto that
turn, and the vehicle warned of that street, only where the turn's connections hold the commit share (95 %) of
the probability of all the fix's candidate connections, of every junction of the cluster (the test adds them up
from the candidates the matcher keeps): the noise put the fix well into the turn, away from the other junctions'
connections. Where the connections of the next junction are rivals, the fix stays on the road.
"""

from __future__ import annotations

import math

import pytest
from junction_town import drive

from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.fixes import MatchState
from csws.road.hmm import Fixes, SequenceMatcher, Track
from csws.road.matching import Probes
from csws.road.roadmap import RoadMap

#: Straight through the cluster: the lanes of the drive (its junction connections filled in).
THROUGH = ["159818918#1_0", "200313016_0", "321426013_0", "321426012_0"]
#: The street the cluster's left turn leads into.
SIDE_STREET = "240545278"
SEEDS = range(60)
#: MatchSettings.commit_share, the share a turn must hold.
COMMIT_SHARE = 0.95


@pytest.fixture(scope="module")
def city() -> RoadMap:
    return RoadMap.load(networks_dir() / "badhersfeld.net.xml.gz")


def _turn_share(city: RoadMap, state: MatchState) -> float:
    """The share of the probability of a fix's candidate junction connections held by those into the side street."""
    into_side = total = 0.0
    for lane_id, log_p in zip(state.candidates, state.log_p, strict=True):
        if city.lane(lane_id).is_internal:
            total += math.exp(log_p)
            into_side += math.exp(log_p) * _leads_into_side_street(city, lane_id)
    return into_side / total


def _leads_into_side_street(city: RoadMap, lane_id: str) -> bool:
    """Whether a junction connection's lanes lead on into the side street."""
    while city.lane(lane_id).is_internal:
        following = city.successors(lane_id)
        if not following:
            return False
        lane_id = following[0]
    return city.lane(lane_id).edge_id == SIDE_STREET


@pytest.mark.parametrize("speed_kmh", [30.0, 40.0])
def test_vehicles_straight_through_a_junction_cluster_are_not_warned_of_its_side_street(
    city: RoadMap, speed_kmh: float
) -> None:
    matcher, engine = SequenceMatcher([city]), Engine(city)
    path = city.expand_path(THROUGH)
    assert not any(city.lane(lane).edge_id == SIDE_STREET for lane in path)
    speed_mps = speed_kmh / 3.6
    for seed in SEEDS:
        route = drive(city, THROUGH, speed_mps, seed, start_m=0.0, length_m=120.0)
        track: Track | None = None
        for k in range(len(route.time_s)):
            fixes = Fixes.of(
                Probes.everywhere(route.xy[k : k + 1]),
                [float(route.time_s[k])],
                [float(route.heading_deg[k])],
                [speed_mps],
                [3.0],
            )
            matched = matcher.match(fixes, [track])
            track = matched.tracks[0]
            lane_id = matched.lane_id[0]
            assert lane_id is not None and track is not None, (seed, k)
            on_turn = city.lane(lane_id).is_internal and _leads_into_side_street(city, lane_id)
            vehicle = VehicleInput(
                f"v{seed}", "M1", speed_kmh, lane_id, float(matched.lane_pos_m[0]), timestamp_s=float(route.time_s[k])
            )
            triggers = engine.evaluate(vehicle).warning.triggers
            warned = any(t.curve_id.startswith(SIDE_STREET) for t in triggers)
            if on_turn or warned:
                assert on_turn and _turn_share(city, track.state) >= COMMIT_SHARE, (seed, k, lane_id, triggers)
