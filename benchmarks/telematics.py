"""Fleet telematics: curve warnings from sampled, noisy GNSS fixes against those from exact lane positions.

A fleet of trucks, buses and cars (the fleet's mix, :mod:`benchmarks.telematics_fleet`) drives in SUMO
on two cities: the bundled Bad Hersfeld network and the Helsinki centre imported from
OpenStreetMap with ``csws import-osm`` (read from ``../shared/data/osm/`` when present; without
it that city is skipped with a line saying so). Helsinki is the city kept out of any tuning: its
figures are the check of what was tuned on Bad Hersfeld. Every vehicle's trajectory is recorded
at 0.1 s. A real ``csws serve`` on loopback (one worker, its vehicles in memory), serving the
city's network alone, is then fed:

* the **reference**: every vehicle's exact lane id and lane position every 0.1 s (one batch per step);
* **exact lane ids** at 1 Hz and 0.2 Hz: the same, sampled: what sampling alone costs;
* **exact lane ids with the receiver's speed noise and drops** at 1 Hz: the sigma 3 m feed's own
  speeds and dropped fixes (the same seed) on exact lane ids, so that what the sigma 3 m feed
  misses beyond it is what its position noise (map matching) costs, and the rest is speed noise
  and drops, which no matcher undoes either;
* **exact positions** at 1 Hz: the true positions and headings sent as fixes, with the sigma 3 m
  feed's speeds and drops, once with ``accuracy_m`` 0.5 m (a precise receiver: what the matcher's
  rules cost, a turn not yet shown and the road's lane for the path ahead, when the fixes can show
  them) and once with 3 m, the sigma 3 m feed's own (the service matches them with the sigma 3 m
  model: what that model's caution costs with no position error); the sigma 3 m feed's figures
  beyond the second are what its realised position errors cost;
* **GNSS fixes** at 1 Hz and 0.2 Hz with sigma 3 m and 8 m position noise (each of east and
  north), 5 deg heading noise, 0.5 km/h speed noise and 2 % of the fixes dropped (fixed seeds),
  as lon/lat, heading, speed and timestamp (and ``accuracy_m``, the sigma, when the service's
  OpenAPI document shows the query accepts it);

each sampled feed as one ``POST /v1/warnings`` batch per second of simulated time (at 0.2 Hz each
vehicle reports in one of five phases, so each batch holds a fifth of the fleet). Each feed's
vehicles have ids of their own, so the service keeps each feed's sessions apart.

Judged per vehicle against the reference's warning onsets (level 0 -> 1 or 2), in time: a feed
onset is the reference's if it comes from 2 fix intervals before to 3 after it, whichever curve it
is for (the lanes of a road share their curves, so the two name the same curve unless the feed's
path ahead went elsewhere; how many pairs name another curve's edge is counted beside). Every noisy
feed is printed beside the exact lane ids at its rate, the **sampling floor**: what sampling
alone costs, which no matcher can undo.

* **missed**: a reference onset with no feed onset from 2 fix intervals before to 3 after it
  while the feed's warning was not already on (one already on, for this curve or another, is
  counted apart as ``already_on``);
* **late**: a matched onset after the reference's, in fix intervals (median and p90 of all
  matched onsets; negative is early);
* **false**: a feed onset with no reference onset in that window while the reference's warning
  stayed off throughout it; with how many reached level 2 and how many came at a junction
  connection (the fix matched to a ``:`` lane, or the warned curve starting on one);
* **repeat onsets** (flicker): onsets within 3 fix intervals of the vehicle's previous warning
  answer, beside the reference's count with the same gap;
* **map matching** (fixes only): the share of fixes matched to an edge the vehicle truly drove on
  within 20 m of travel before or after the fix ("the true road": an error along the road is
  not a wrong road, a wrong connection or side street is), to its exact lane, and answered
  with no match;
* **us per fix**: the service's own time (its ``Server-Timing`` header) per fix;
* **reference methods** (sigma 8 m at 1 Hz): the same fixes matched in-process online, once one
  and two more fixes have arrived (the lag window), by the full-trace Viterbi, by the nearest road,
  and whether the true road is a candidate at all, and the share within sigma of two roads
  (:mod:`benchmarks.telematics_reference`): what any matcher can reach. The issue's 97 % of fixes on
  the true road is judged once the next fix has arrived (lag 1): the issue asks for a fix inside a
  junction to be matched to the connection the vehicle takes "as soon as the next fix shows it"; an
  answer given when its fix arrives cannot know it, and stays on the road's continuation until then
  (that share, at the answer, is printed beside).

Each run's figures are written as a line of ``telematics.jsonl`` in the output directory
(``out/telematics/`` by default) as soon as it is measured, with every missed and false onset named
(``onsets_named``: the vehicle, the time, the lane it drove, the lane its fix was matched to, the warned
curve's edge), beside the issue's targets (At 1 Hz
sigma 3 m: missed at most the exact 1 Hz feed's, false at most 0.5 % of the reference onsets, no
level-2 false warning at a junction connection, p90 lateness at most one fix interval, repeat
onsets at most 1.2 times the reference's; at sigma 8 m: at least 97 % of fixes matched to the true
road once the next fix has arrived, at most 1 % no-match faults).

Run with ``python -m benchmarks.telematics [--quick] [--out DIR]``: about 4.5 CPU-minutes in all
(SUMO, the client and the service, which mostly take turns): 9.5 minutes measured on two cores
shared with other work (load average 5 to 7), 20 minutes at load average 8 to 9. ``--quick``
does about a fifth of the work (4 minutes at load average 9). ``--city "Bad Hersfeld"`` runs one city
(by the start of its name), ``--one-hz`` the 1 Hz feeds alone, those the issue's targets are on (the
Bad Hersfeld quick fleet at 1 Hz: some 2 minutes at load average 7).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from benchmarks.rows import Row, at_least, at_most, context, table
from benchmarks.servers import csws_serve
from benchmarks.telematics_analysis import Noise
from benchmarks.telematics_feed import FeedAnswers, Sends, feed_service, query_fields
from benchmarks.telematics_fleet import STEP_S, Trajectories, drive_fleet
from benchmarks.telematics_judge import judge
from benchmarks.telematics_reference import reference_figures
from benchmarks.telematics_reference import summary as reference_summary
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap

#: The repository's neighbour holding the shared data (read at run time only, when present).
SHARED_DIR = Path(__file__).resolve().parents[1].parent / "shared"
HELSINKI_OSM = SHARED_DIR / "data" / "osm" / "helsinki-centre.osm.gz"
CITY_NET = networks_dir() / "badhersfeld.net.xml.gz"
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "out" / "telematics"

#: The GNSS receivers: sigma 3 m and 8 m of position, 5 deg of heading, 0.5 km/h of speed, 2 % dropped.
NOISE_3_M = Noise(position_sigma_m=3.0, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.02)
NOISE_8_M = Noise(position_sigma_m=8.0, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.02)
#: A precise receiver's accuracy claimed for exact positions (its speed noise and drops are the sigma 3 m one's).
PRECISE_0_5_M = Noise(position_sigma_m=0.5, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.02)

#: Targets of the issue (at 1 Hz, sigma 3 m and 8 m).
TARGET_FALSE_SHARE = 0.005
TARGET_P90_LATE_INTERVALS = 1.0
TARGET_REPEAT_RATIO = 1.2
TARGET_TRUE_ROAD_SHARE = 0.97
TARGET_NO_MATCH_SHARE = 0.01


@dataclass(frozen=True)
class Feed:
    """One way of feeding the service: how often, and with which receiver (None: exact lane ids)."""

    name: str
    interval_s: float
    noise: Noise | None
    seed: int
    sends: Sends = Sends.FIXES
    """What a feed with a receiver sends of its measurements."""

    @property
    def sends_positions(self) -> bool:
        """Whether the feed sends positions (which the service map-matches), not lane ids."""
        return self.noise is not None and self.sends is not Sends.EXACT_LANES


REFERENCE = Feed("reference: exact lane ids, 10 Hz", STEP_S, None, 0)
EXACT_1_HZ = Feed("exact lane ids, 1 Hz", 1.0, None, 0)
SIGMA_3_1_HZ = Feed("sigma 3 m, 1 Hz", 1.0, NOISE_3_M, 1)
SIGMA_8_1_HZ = Feed("sigma 8 m, 1 Hz", 1.0, NOISE_8_M, 2)
EXACT_RECEIVER_1_HZ = Feed(
    "exact lane ids with the sigma 3 m receiver's speed noise and drops, 1 Hz",
    1.0,
    NOISE_3_M,
    SIGMA_3_1_HZ.seed,
    Sends.EXACT_LANES,
)
EXACT_POSITIONS_1_HZ = Feed(
    "exact positions claimed at 3 m, with the sigma 3 m receiver's speed noise and drops, 1 Hz",
    1.0,
    NOISE_3_M,
    SIGMA_3_1_HZ.seed,
    Sends.EXACT_POSITIONS,
)
PRECISE_POSITIONS_1_HZ = Feed(
    "exact positions claimed at 0.5 m, with the sigma 3 m receiver's speed noise and drops, 1 Hz",
    1.0,
    PRECISE_0_5_M,
    SIGMA_3_1_HZ.seed,
    Sends.EXACT_POSITIONS,
)
FEEDS = (
    EXACT_1_HZ,
    EXACT_RECEIVER_1_HZ,
    PRECISE_POSITIONS_1_HZ,
    EXACT_POSITIONS_1_HZ,
    SIGMA_3_1_HZ,
    SIGMA_8_1_HZ,
    Feed("exact lane ids, 0.2 Hz", 5.0, None, 0),
    Feed("sigma 3 m, 0.2 Hz", 5.0, NOISE_3_M, 3),
    Feed("sigma 8 m, 0.2 Hz", 5.0, NOISE_8_M, 4),
)


@dataclass(frozen=True)
class City:
    """A city of the benchmark: its network (or the OSM extract it is imported from) and its fleet."""

    name: str
    net: Path | None
    osm: Path | None
    vehicles: int
    duration_s: float
    quick_vehicles: int
    quick_duration_s: float


CITIES = (
    City("Bad Hersfeld", CITY_NET, None, 150, 600.0, 60, 180.0),
    City("Helsinki centre", None, HELSINKI_OSM, 60, 600.0, 30, 180.0),
)


def _log(text: str) -> None:
    """A progress line on stderr."""
    print(text, file=sys.stderr, flush=True)


def _network(city: City, out: Path) -> Path | None:
    """The city's network: bundled, or imported from its OSM extract with ``csws import-osm`` (None if absent)."""
    if city.net is not None:
        return city.net
    if city.osm is None or not city.osm.is_file():
        return None
    net = out / f"{city.name.split()[0].lower()}.net.xml.gz"
    _log(f"{city.name}: csws import-osm {city.osm} ...")
    command = [sys.executable, "-m", "csws", "import-osm", str(city.osm), "-o", str(net)]
    subprocess.run(command, check=True, stdout=sys.stderr)
    return net


def _summary_line(city: str, feed: Feed, figures: dict) -> str:
    """One run's figures in one line."""
    late = figures["late_intervals"]
    text = (
        f"{city} | {feed.name}: {figures['fixes']:,} fixes, {figures['onsets']:,} onsets "
        f"(reference {figures['reference_onsets']:,}); missed {figures['missed']:,} "
        f"({figures['missed_share']:.1%}); late {late['late']:,}, median {late['median']:.2f}, "
        f"p90 {late['p90']:.2f} intervals, {figures['other_curve']:,} on another curve's edge; "
        f"false {figures['false']:,} ({figures['false_share']:.2%}; "
        f"level 2 {figures['false_level_2']:,}, at a junction connection {figures['false_junction']:,}, "
        f"both {figures['false_level_2_junction']:,}); repeat onsets {figures['repeats']:,} vs "
        f"{figures['reference_repeats']:,}"
    )
    matching = figures.get("matching")
    if matching:
        text += (
            f"; true road {matching['true_road_share']:.1%}, true lane {matching['true_lane_share']:.1%}, "
            f"no match {matching['no_match_share']:.2%}"
        )
    return text + f"; {figures['us_per_fix']:.0f} us per fix"


@dataclass(frozen=True)
class _Prepared:
    """A city ready to be fed: its network and its fleet's trajectories (or why it was skipped)."""

    net: Path | None
    trajectories: Trajectories | None
    duration_s: float
    skipped: str | None = None


def _prepare(city: City, quick: bool, out: Path) -> _Prepared:
    """A city's network (imported if need be) and its fleet driven in SUMO."""
    vehicles, duration_s = (city.quick_vehicles, city.quick_duration_s) if quick else (city.vehicles, city.duration_s)
    net = _network(city, out)
    if net is None:
        return _Prepared(None, None, duration_s, f"{city.name}: skipped, no OpenStreetMap extract at {city.osm}")
    _log(f"{city.name}: driving {vehicles} vehicles for {duration_s:g} s in SUMO ...")
    started = time.perf_counter()
    trajectories = drive_fleet(net, vehicles, duration_s)
    _log(
        f"{city.name}: {len(trajectories.vehicle_ids)} vehicles, {len(trajectories.step):,} steps recorded "
        f"in {time.perf_counter() - started:.0f} s"
    )
    return _Prepared(net, trajectories, duration_s)


def _city_runs(city: City, prepared: _Prepared, sink: IO[str], feeds: tuple[Feed, ...] = FEEDS) -> dict:
    """One city: start its service, feed it each of ``feeds`` and judge each against the reference."""
    if prepared.net is None or prepared.trajectories is None:
        print(prepared.skipped, flush=True)
        return {"skipped": prepared.skipped}
    service = csws_serve(Path(":memory:"), "--net", str(prepared.net))
    try:
        _log(f"{city.name}: csws serve ready in {service.startup_s:.0f} s")
        runs = _fed(city.name, prepared.net, prepared.trajectories, service.url, sink, feeds)
    finally:
        service.stop()
    return {"vehicles": len(prepared.trajectories.vehicle_ids), "duration_s": prepared.duration_s, "feeds": runs}


def _fed(
    city: str, net: Path, trajectories: Trajectories, url: str, sink: IO[str], feeds: tuple[Feed, ...] = FEEDS
) -> dict:
    """The service fed the reference, then each of ``feeds``, each judged against the reference."""
    fields = query_fields(url)
    _log(f"{city}: the query schema takes accuracy_m: {fields.accuracy or 'no (not sent)'}")
    started = time.perf_counter()
    reference = feed_service(url, net, trajectories, REFERENCE, "f0", fields, _log)
    _log(
        f"{city}: reference fed in {time.perf_counter() - started:.0f} s, "
        f"{1000.0 * reference.server_ms / len(reference.rows):.0f} us per query in the service"
    )
    runs = {}
    for index, feed in enumerate(feeds, start=1):
        answers = feed_service(url, net, trajectories, feed, f"f{index}", fields, _log)
        runs[feed.name] = _judged(city, feed, trajectories, reference, answers, sink)
    if SIGMA_8_1_HZ in feeds:
        runs[SIGMA_8_1_HZ.name]["matching"]["reference"] = _bounds(city, net, trajectories)
    return runs


def _bounds(city: str, net: Path, trajectories: Trajectories) -> dict:
    """The reference methods on the sigma 8 m 1 Hz fixes the service was sent (in-process): what any matcher
    can reach with them, printed beside the service's figure."""
    assert SIGMA_8_1_HZ.noise is not None
    started = time.perf_counter()
    figures = reference_figures(RoadMap.load(net), trajectories, SIGMA_8_1_HZ.noise, SIGMA_8_1_HZ.seed)
    print(f"{city} | {SIGMA_8_1_HZ.name}, reference methods: {reference_summary(figures)}", flush=True)
    _log(f"{city}: reference methods in {time.perf_counter() - started:.0f} s")
    return figures


def _judged(
    city: str, feed: Feed, trajectories: Trajectories, reference: FeedAnswers, answers: FeedAnswers, sink: IO[str]
) -> dict:
    """A feed's figures against the reference, printed and written to the JSON lines file at once."""
    figures = judge(trajectories, reference, answers, feed.interval_s, matching=feed.sends_positions)
    print(_summary_line(city, feed, figures), flush=True)
    sink.write(json.dumps({"city": city, "feed": feed.name, **figures}) + "\n")
    sink.flush()
    return figures


def run(
    quick: bool = False, out: Path = DEFAULT_OUT, cities: tuple[City, ...] = CITIES, feeds: tuple[Feed, ...] = FEEDS
) -> dict:
    """The runs of ``cities`` (all by default) with ``feeds``, their figures streamed to ``out/telematics.jsonl``."""
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    # one city after another is prepared in the background while the one before is fed
    with open(out / "telematics.jsonl", "w", encoding="utf-8") as sink, ThreadPoolExecutor(1) as preparing:
        prepared = [preparing.submit(_prepare, city, quick, out) for city in cities]
        runs = {
            city.name: _city_runs(city, ready.result(), sink, feeds)
            for city, ready in zip(cities, prepared, strict=True)
        }
    return {"cities": runs, "quick": quick, "seconds": time.perf_counter() - started}


def _floor(figures: dict, exact: dict) -> str:
    """What the exact lane ids at a feed's rate give (sampling alone), to read the feed's figures against."""
    if figures is exact:
        return "the sampling floor"
    return (
        f"sampling floor (exact lane ids): {exact['missed']} / {exact['late_intervals']['p90']:.2f} / "
        f"{exact['false']} / {exact['repeats']}"
    )


def _sigma_3_rows(name: str, sigma_3: dict, exact: dict, receivers: tuple[dict | None, ...]) -> list[Row]:
    """The issue's targets at 1 Hz and sigma 3 m, each beside the exact 1 Hz feed's figure (sampling alone) and,
    for missed and false, beside the same receiver's speed noise and drops sent with exact lane ids, with exact
    positions claimed at 0.5 m and at 3 m (``receivers``, where run): from the sampling floor to the first is the
    receiver's speeds and drops, to the second what the matcher's rules cost, to the third the caution of the
    sigma 3 m model, to sigma 3 m the realised position errors."""
    reference_onsets = sigma_3["reference_onsets"]
    prefix = f"telematics {name}, {SIGMA_3_1_HZ.name}:"
    floor = "exact 1 Hz (sampling alone): {}"
    on_lanes, precise, at_3_m = receivers

    def beside(figure: str) -> str:
        """The floor's figure, and the receiver's without its position noise on exact lanes and positions."""
        text = floor.format(exact[figure])
        text += f"; with the receiver's speed noise and drops: {on_lanes[figure]}" if on_lanes else ""
        text += f"; matched from exact positions claimed at 0.5 m: {precise[figure]}" if precise else ""
        return text + (f", at 3 m: {at_3_m[figure]}" if at_3_m else "")

    return [
        at_most(f"{prefix} missed", sigma_3["missed"], exact["missed"], beside("missed")),
        at_most(
            f"{prefix} false warnings",
            sigma_3["false"],
            TARGET_FALSE_SHARE * reference_onsets,
            f"{reference_onsets:,} reference onsets; level 2 {sigma_3['false_level_2']}; " + beside("false"),
        ),
        at_most(
            f"{prefix} level-2 false warnings at a junction connection",
            sigma_3["false_level_2_junction"],
            0,
            beside("false_level_2_junction"),
        ),
        at_most(
            f"{prefix} p90 lateness, fix intervals",
            sigma_3["late_intervals"]["p90"],
            TARGET_P90_LATE_INTERVALS,
            floor.format(f"{exact['late_intervals']['p90']:.2f}"),
        ),
        at_most(
            f"{prefix} repeat onsets",
            sigma_3["repeats"],
            TARGET_REPEAT_RATIO * sigma_3["reference_repeats"],
            f"reference {sigma_3['reference_repeats']}; " + floor.format(exact["repeats"]),
        ),
    ]


def _sigma_8_rows(name: str, sigma_8: dict) -> list[Row]:
    """The issue's matching targets at 1 Hz and sigma 8 m: the true road judged once the next fix has arrived
    (the issue's lag window: a fix inside a junction on the connection the next fix shows), the share at the
    answer itself and the reference methods beside it."""
    prefix = f"telematics {name}, {SIGMA_8_1_HZ.name}:"
    matching = sigma_8["matching"]
    bounds = matching.get("reference")
    rows = [
        context(f"{prefix} fixes on the true road at their own answer (service)", round(matching["true_road_share"], 4))
    ]
    rows.append(
        at_least(
            f"{prefix} fixes on the true road once the next fix has arrived (service's confirmed)",
            round(matching["confirmed_true_road_share"], 4),
            TARGET_TRUE_ROAD_SHARE,
            (
                f"in-process lag 1 {bounds['lag_1_true_road_share']:.1%}, after 2 fixes "
                f"{bounds['lag_2_true_road_share']:.1%}"
            )
            if bounds
            else "",
        )
    )
    if bounds:
        rows += [
            context(
                f"{prefix} true road online (in-process) / full-trace Viterbi / nearest road / reachable at all",
                f"{bounds['online_true_road_share']:.1%} / {bounds['full_trace_true_road_share']:.1%} / "
                f"{bounds['nearest_true_road_share']:.1%} / {bounds['reachable_true_road_share']:.1%}",
                f"within sigma of 2+ roads {bounds['ambiguous_share']:.1%}",
            ),
        ]
    rows.append(at_most(f"{prefix} no-match faults", round(matching["no_match_share"], 4), TARGET_NO_MATCH_SHARE))
    return rows


def _city_rows(name: str, city: dict) -> list[Row]:
    """One city's rows: the issue's targets on the 1 Hz feeds, the other feeds for context, each noisy feed
    beside the exact lane ids at its rate (what sampling alone costs)."""
    if "skipped" in city:
        return [Row(f"telematics {name}", "skipped", "", None, city["skipped"])]
    feeds = city["feeds"]
    exact = feeds[EXACT_1_HZ.name]
    receivers = tuple(feeds.get(f.name) for f in (EXACT_RECEIVER_1_HZ, PRECISE_POSITIONS_1_HZ, EXACT_POSITIONS_1_HZ))
    rows = _sigma_3_rows(name, feeds[SIGMA_3_1_HZ.name], exact, receivers) + _sigma_8_rows(
        name, feeds[SIGMA_8_1_HZ.name]
    )
    for feed in FEEDS:
        figures = feeds.get(feed.name)
        if figures is None:
            continue
        floor = feeds[next(f.name for f in FEEDS if f.noise is None and f.interval_s == feed.interval_s)]
        rows.append(
            context(
                f"telematics {name}, {feed.name}: missed / late p90 / false / repeats",
                f"{figures['missed']} / {figures['late_intervals']['p90']:.2f} / {figures['false']} / "
                f"{figures['repeats']}",
                f"{_floor(figures, floor)}; {figures['us_per_fix']:.0f} us per fix",
            )
        )
    return rows


def rows(figures: dict) -> list[Row]:
    """Every city's rows."""
    return [row for name, city in figures["cities"].items() for row in _city_rows(name, city)]


def main(argv: list[str] | None = None) -> int:
    """Run, print each run's line as it is measured, then the table beside the targets."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.telematics", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller fleets for a shorter time")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory (default out/telematics)")
    parser.add_argument("--city", action="append", help="run only the city whose name starts with this (repeatable)")
    parser.add_argument("--one-hz", action="store_true", help="only the 1 Hz feeds (those the targets are on)")
    args = parser.parse_args(argv)
    cities = tuple(city for city in CITIES if not args.city or any(city.name.startswith(n) for n in args.city))
    if not cities:
        parser.error(
            f"no city starts with {' or '.join(args.city)}: the cities are {', '.join(c.name for c in CITIES)}"
        )
    feeds = tuple(feed for feed in FEEDS if feed.interval_s == 1.0) if args.one_hz else FEEDS
    figures = run(args.quick, args.out, cities, feeds)
    print(table(rows(figures)))
    print(f"{figures['seconds']:.0f} s; every run's figures in {args.out / 'telematics.jsonl'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
