"""How a JT/T 808 gateway (:mod:`service.jt808`) listens, what it allows a connection and what it tells drivers."""

from __future__ import annotations

from dataclasses import dataclass, field

from csws.gateways.jt808.reassembly import PACKAGE_WAIT_S
from csws.gateways.jt808.texts import DriverTexts
from csws.gateways.jt808.tracking import TrackingSettings

__all__ = ["GatewaySettings"]


@dataclass(frozen=True)
class GatewaySettings:
    """How the gateway listens and what it allows a connection.

    Attributes
    ----------
    idle_s
        A connection that sends nothing this long is closed (three missed 60 s heartbeats, the
        standard's default heartbeat interval).
    frames_per_s, frames_burst
        Each connection may send this many frames per second on average, this many at once;
        the excess is dropped (and logged, rate-limited).
    max_connections
        Connections beyond this many are closed at once.
    package_wait_s
        A sub-packaged message whose packages have not all come is asked for the missing ones (``0x8003``)
        after this long without a package, a few times (:mod:`csws.gateways.jt808.reassembly`), s.
    batch_window_s
        A group of reports starts at most this often (:class:`service.jt808_groups.Batcher`): a group
        costs a few milliseconds whatever its size (map matching, the engine, the state store's round
        trips) and little more per report, so reports answered together cost far less than a handful
        at a time, for at most this much more latency.
    tracking
        When and how slow terminals are asked for temporary tracking (``0x8202``) near a curve.
    untracked_fleets
        The fleets whose terminals are never asked for tracking (``*``: none is).
    """

    host: str = "127.0.0.1"
    port: int = 6808
    idle_s: float = 180.0
    frames_per_s: float = 20.0
    frames_burst: float = 60.0
    max_connections: int = 20_000
    package_wait_s: float = PACKAGE_WAIT_S
    batch_window_s: float = 0.02
    fleet_texts: dict[str, DriverTexts] = field(default_factory=dict)
    tracking: TrackingSettings = field(default_factory=TrackingSettings)
    untracked_fleets: frozenset[str] = frozenset()

    def texts(self, fleet: str) -> DriverTexts:
        """The texts of ``fleet`` (the defaults where it has none)."""
        return self.fleet_texts.get(fleet, DriverTexts())

    def tracks(self, fleet: str) -> bool:
        """Whether ``fleet``'s slow terminals are asked for temporary tracking near a curve."""
        return not ({fleet, "*"} & self.untracked_fleets)
