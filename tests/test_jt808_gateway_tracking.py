"""Temporary location tracking (0x8202) through the real gateway on loopback (the rig of tests/jt808_rig.py): a
slow terminal is asked for 1 s reports before the curve and warned in time; a fleet left out is warned late; a
refusal is not asked again; a late terminal's tracked reports never count as its regular interval.
"""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import pytest
from jt808_rig import (
    APPROACH_M,
    ARC_DEG,
    CATEGORY,
    FLEET,
    ON_A_FREE_PORT,
    RADIUS_M,
    START_TOLERANCE_M,
    Drive,
    Rig,
    build_net,
    connected,
    formula_1_m,
)

import service.jt808
from csws.gateways.jt808.tracking import TrackingSettings
from csws.standard import warning_speed
from csws.warning.rules import WarningSettings
from service.jt808_settings import GatewaySettings

pytestmark = [pytest.mark.sumo, pytest.mark.slow]


@pytest.fixture(scope="module")
def net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_net(tmp_path_factory.mktemp("jt808"))


SLOW_KMH = 80.0


def _warning_point_m(interval_s: float) -> float:
    """Where the warning must be on at the latest for a terminal reporting every ``interval_s``, m before the curve:
    S_w of formula (1) at :data:`SLOW_KMH`, plus the distance driven in the engine's latency (the period it learns,
    at most its cap, and the system delay)."""
    settings = WarningSettings()
    speed_mps = SLOW_KMH / 3.6
    period_s = min(interval_s, settings.max_update_period_s)
    return formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1)) + speed_mps * (
        period_s + settings.system_delay_s
    )


def _ask_m(interval_s: float) -> float:
    """Where a report is placed, m before the curve: the first from which the next regular report could pass the
    warning point. The next regular one would lie halfway to formula (1)'s point where the period is longer than
    the engine's cap (late), else half a second past the warning point."""
    speed_mps, sw_m = SLOW_KMH / 3.6, formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1))
    point_m = _warning_point_m(interval_s)
    return point_m + max(0.5 * speed_mps, speed_mps * interval_s - (point_m - sw_m) - sw_m / 2)


def _slow_drive(
    net: Path,
    folder: Path,
    interval_s: float,
    settings: GatewaySettings = ON_A_FREE_PORT,
    tracking_answer: tuple[int, bool] = (0, True),
):
    """A terminal at :data:`SLOW_KMH` reporting every ``interval_s``, from four intervals before :func:`_ask_m`
    until its first text; the drive (with the tracking requests it was sent) and the texts."""
    start_m = _ask_m(interval_s) + 4 * SLOW_KMH / 3.6 * interval_s

    async def run() -> tuple[Drive, list[tuple[float, str]]]:
        async with Rig(net, folder, settings) as rig:
            terminal = await connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - start_m, interval_s, tracking_answer)
            texts: list[tuple[float, str]] = []
            while not texts:
                assert drive.x_m < APPROACH_M, "no warning before the curve"
                texts += await drive.report(SLOW_KMH)
            await terminal.close()
            return drive, texts

    return asyncio.run(run())


@pytest.mark.parametrize("interval_s", [5.0, 10.0])
def test_a_slow_terminal_is_tracked_before_the_curve_and_warned_in_time(net, tmp_path, interval_s):
    v_w1, speed_mps = warning_speed(RADIUS_M, CATEGORY, 1), SLOW_KMH / 3.6
    sw_m, point_m = formula_1_m(SLOW_KMH, v_w1), _warning_point_m(interval_s)
    drive, texts = _slow_drive(net, tmp_path, interval_s)
    [(asked_m, tracking_s, validity_s)] = drive.asked  # once, and not again while its window runs
    # At the first report from which the next regular one could pass the warning point, not at the one before.
    assert asked_m == pytest.approx(_ask_m(interval_s), abs=START_TOLERANCE_M)
    assert asked_m - speed_mps * interval_s <= point_m < asked_m
    # 1 s reports until the curve is left at its level-1 V_w, and a margin.
    leave_s = (asked_m + RADIUS_M * math.radians(ARC_DEG)) / (v_w1 / 3.6)
    assert tracking_s == 1 and leave_s - 1.0 <= validity_s <= leave_s + 12.0
    [(onset_m, text)] = texts
    assert "前方弯道" in text and onset_m < asked_m
    # In time: shown before formula (1)'s point at the latest, and not before the warning point.
    assert onset_m - speed_mps * WarningSettings().system_delay_s >= sw_m - START_TOLERANCE_M
    assert onset_m <= point_m + START_TOLERANCE_M


def test_a_terminal_slower_than_the_cap_and_not_tracked_is_warned_late(net, tmp_path):
    """The same drive at 10 s with its fleet not tracked: the report after the one that would have asked lies
    halfway to formula (1)'s point, and the warning comes only there (the allowance stops at 5 s)."""
    interval_s, speed_mps = 10.0, SLOW_KMH / 3.6
    drive, texts = _slow_drive(net, tmp_path, interval_s, GatewaySettings(port=0, untracked_fleets=frozenset({FLEET})))
    assert drive.asked == []
    [(onset_m, text)] = texts
    assert "前方弯道" in text
    assert onset_m == pytest.approx(_ask_m(interval_s) - speed_mps * interval_s, abs=START_TOLERANCE_M)
    assert onset_m < formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1)) - START_TOLERANCE_M


@pytest.mark.parametrize("result, asked", [(0, 2), (3, 1)])
def test_a_terminal_that_refuses_tracking_is_not_asked_again(net, tmp_path, result, asked):
    """Windows of 5 s that end with their validity (no overrun: a terminal never seen at the tracked pace is let go
    only that much after the window's end), and a terminal at 10 s that keeps its interval: once a window has run
    out, the curve still ahead is asked for again, unless the terminal refused the first request (result 3: not
    supported)."""
    settings = GatewaySettings(port=0, tracking=TrackingSettings(max_window_s=5, overrun_s=0.0))
    drive, texts = _slow_drive(net, tmp_path, 10.0, settings, tracking_answer=(result, False))
    assert len(drive.asked) == asked and [validity_s for _, _, validity_s in drive.asked] == [5] * asked
    assert len(texts) == 1  # the reports go on being answered and warned


def test_a_late_terminals_tracked_reports_never_count_as_its_regular_interval(net, tmp_path, monkeypatch):
    """A terminal at 10 s whose reports reach the gateway 1.5 s late (not yet stale), and the 0x8202 the terminal
    2 s after that, asked for 5 s windows: it reports every second from the request's arrival until 5 s after,
    up to 3.5 s past the asking report's time plus the validity, then every 10 s again. The gateway's connection
    learns only 10 s intervals, never one of the 1 s ones, so it still takes the terminal for slow."""
    uplink_s, downlink_s, interval_s = 1.5, 2.0, 10.0
    conversations: list[service.jt808.Conversation] = []

    class Recorded(service.jt808.Conversation):
        def __init__(self, *args: Any) -> None:
            super().__init__(*args)
            conversations.append(self)

    monkeypatch.setattr(service.jt808, "Conversation", Recorded)
    settings = GatewaySettings(port=0, tracking=TrackingSettings(max_window_s=5))
    start_m = _ask_m(interval_s) + 4 * SLOW_KMH / 3.6 * interval_s

    async def run() -> Drive:
        async with Rig(net, tmp_path, settings) as rig:
            terminal = await connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - start_m, interval_s, uplink_s=uplink_s, downlink_s=downlink_s)
            asked_at_s = math.inf
            while drive.time_s < asked_at_s + uplink_s + downlink_s + 5.0 + 4 * interval_s:
                await drive.report(SLOW_KMH)
                if drive.asked and asked_at_s == math.inf:
                    asked_at_s = drive.time_s
                assert drive.reports < 60, "never asked for tracking"
            await terminal.close()
            return drive

    drive = asyncio.run(run())
    [conversation] = conversations
    assert drive.asked and all(validity_s == 5 for _, _, validity_s in drive.asked)
    assert set(conversation.pace.intervals_s) == {interval_s}
    assert conversation.pace.regular_interval_s() == interval_s
