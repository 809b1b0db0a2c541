"""The service's settings: command-line options override environment variables (``CSWS_*``).

Every setting can come from the environment, so that ``uvicorn service.app:app`` is configured
the same way as ``csws serve``:

``CSWS_NETS`` (network files separated by ``os.pathsep``; default the bundled city), ``CSWS_TEST_TRACKS``,
``CSWS_HOST``, ``CSWS_PORT``, ``CSWS_WORKERS``, ``CSWS_STATE``, ``CSWS_STATE_DB``, ``CSWS_SESSION_IDLE_S``,
``CSWS_EVENT_RETENTION_S``, ``CSWS_EVENT_RETENTION_BY_FLEET`` (a JSON object of seconds by fleet),
``CSWS_MATCH_TOLERANCE_M``, ``CSWS_HEADING_TOLERANCE_DEG``, ``CSWS_MATCH_ACCURACY_M``, ``CSWS_MATCH_SEARCH_SIGMAS``,
``CSWS_MATCH_HEADING_SIGMA_DEG``, ``CSWS_MATCH_LANE_CHANGE_LOG_P``, ``CSWS_MATCH_DEAD_RECKONING_S``,
``CSWS_UPDATE_PERIOD_S``, ``CSWS_LEARN_UPDATE_PERIOD``, ``CSWS_ACTIVATION_SPEED_KMH``,
``CSWS_MAX_UPDATE_PERIOD_S``, ``CSWS_SYSTEM_DELAY_S``, ``CSWS_RELEASE_MARGIN_KMH``, ``CSWS_RELEASE_HOLD_S``,
``CSWS_RELEASE_HOLD_INTERVALS``,
``CSWS_API_KEYS_FILE``, ``CSWS_FCW_SETTINGS_FILE``, ``CSWS_WARNING_SETTINGS_FILE``, ``CSWS_INSECURE``,
``CSWS_PUBLIC_DOCS``, ``CSWS_MAX_BODY_BYTES``,
``CSWS_BODY_TIMEOUT_S``, ``CSWS_HEAD_TIMEOUT_S``,
``CSWS_MQTT``, ``CSWS_WEBHOOKS_FILE``, ``CSWS_WEBHOOK_ALLOW_PRIVATE``, ``CSWS_PUSH_DB`` (push, docs/push.md).

Without an API key file (:mod:`service.keys`) the service answers anyone, so it listens
only on a loopback address unless ``insecure`` is set.
"""

from __future__ import annotations

import ipaddress
import os
from dataclasses import replace
from pathlib import Path
from typing import Annotated
from urllib.parse import urlsplit

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from csws.engine import EngineSettings
from csws.road.match_settings import MatchSettings
from csws.warning.rules import WarningSettings

from .keys import FLEET_PATTERN
from .networks import city_network_paths, track_network_paths
from .store import DEFAULT_EVENT_RETENTION_S, MAX_SESSION_IDLE_S

__all__ = ["ServiceSettings", "default_state_db"]

#: The library's defaults, which the service's settings start from (none is repeated here).
_ENGINE = EngineSettings()
_MATCH = MatchSettings()
_WARNING: WarningSettings = _ENGINE.warning


#: The schemes of a Redis URL (``--state``): plain TCP, TLS, a Unix socket.
REDIS_SCHEMES = ("redis", "rediss", "unix")


def default_state_db() -> Path:
    """Where the vehicles' state persists by default: ``$XDG_STATE_HOME/csws/vehicles.sqlite3``."""
    state_home = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(state_home) / "csws" / "vehicles.sqlite3"


class ServiceSettings(BaseSettings):
    """How the service runs and what it serves."""

    model_config = SettingsConfigDict(env_prefix="CSWS_", allow_inf_nan=False)

    nets: Annotated[list[Path], NoDecode] = Field(
        default_factory=list,
        description="SUMO networks to serve (default: the bundled city, Bad Hersfeld; with test_tracks, none)",
    )
    test_tracks: bool = Field(
        default=False,
        description="also serve the bundled test tracks of T/ITS 0091-2018 (instead of the city when no nets are "
        "given); they share their coordinates, so a fix should name its network",
    )
    host: str = Field(default="127.0.0.1", description="address to listen on")
    port: int = Field(default=8000, ge=0, le=65535, description="TCP port")
    workers: int = Field(default=1, ge=1, le=64, description="worker processes")
    state: str = Field(
        default="",
        description="redis://HOST:PORT/DB: the Redis keeping vehicle switches, categories and sessions for every "
        "worker and replica; empty: the SQLite file state_db",
    )
    state_db: str = Field(
        default_factory=lambda: str(default_state_db()),
        description="SQLite file keeping vehicle switches, categories and sessions for the workers of this machine "
        "and across restarts, when state names no Redis; ':memory:' keeps them in memory only, for one worker",
    )
    session_idle_s: float = Field(default=600.0, gt=0, description="a vehicle session idle this long expires, s")
    event_retention_s: float = Field(
        default=DEFAULT_EVENT_RETENTION_S,
        gt=0,
        le=MAX_SESSION_IDLE_S,
        description="the outbox keeps each warning event this long, s (docs/events.md; default 7 days)",
    )
    event_retention_by_fleet: dict[str, Annotated[float, Field(gt=0, le=MAX_SESSION_IDLE_S)]] = Field(
        default_factory=dict,
        description='fleets whose warning events are kept for a time of their own, s by fleet, e.g. {"acme": 86400} '
        "(JSON); the others' are kept for event_retention_s",
    )
    match_tolerance_m: float = Field(
        default=_MATCH.tolerance_m, gt=0, description="a fix matches lanes within this distance, m"
    )
    heading_tolerance_deg: float = Field(
        default=_MATCH.heading_tolerance_deg, gt=0, le=180, description="allowed heading difference, deg"
    )
    match_accuracy_m: float = Field(
        default=_MATCH.accuracy_m,
        gt=0,
        description="the standard deviation of a fix's position where the query gives no accuracy_m, m: the "
        "sequence matcher weighs a fix's distance from a lane and searches lanes by it (csws.road.hmm)",
    )
    match_search_sigmas: float = Field(
        default=_MATCH.search_sigmas,
        gt=0,
        description="the sequence matcher's candidates lie within this many standard deviations of the fix "
        "(never nearer than match_tolerance_m)",
    )
    match_heading_sigma_deg: float = Field(
        default=_MATCH.heading_sigma_deg,
        gt=0,
        description="the standard deviation of a fix's heading against its lane's direction, deg",
    )
    match_lane_change_log_p: float = Field(
        default=_MATCH.lane_change_log_p,
        le=0,
        description="the log-probability of a change to another lane of the same edge between two fixes",
    )
    match_dead_reckoning_s: float = Field(
        default=_MATCH.dead_reckoning_s,
        ge=0,
        description="a fix matching no lane is dead-reckoned along the road this long after the last match, s",
    )
    match_standstill_mps: float = Field(
        default=_MATCH.standstill_mps,
        ge=0,
        description="a fix slower than this is standing (waiting at a stop line), m/s: see the two penalties below",
    )
    match_standstill_edge_log_p: float = Field(
        default=_MATCH.standstill_edge_log_p,
        le=0,
        description="the log-probability of moving to another edge between two standing fixes",
    )
    match_standstill_junction_log_p: float = Field(
        default=_MATCH.standstill_junction_log_p,
        le=0,
        description="the log-probability added to a junction's lane as the match of a standing fix",
    )
    update_period_s: float = Field(
        default=_WARNING.update_period_s,
        ge=0,
        description="how often a vehicle's fixes arrive, s: until its own period is learnt from its timestamps, "
        "or always where learn_update_period is off",
    )
    learn_update_period: bool = Field(
        default=_WARNING.learn_update_period,
        description="learn each vehicle's update period from its timestamps (the median of its last intervals); "
        "off pins every vehicle's to update_period_s",
    )
    max_update_period_s: float = Field(
        default=_WARNING.max_update_period_s, ge=0, description="the longest update period learnt, s"
    )
    system_delay_s: float = Field(default=_WARNING.system_delay_s, ge=0, description="processing and display delay, s")
    release_margin_kmh: float = Field(
        default=_WARNING.release_margin_kmh,
        ge=0,
        le=50,
        description="the release rule's margin: a level that is on goes off this far below V_w, km/h",
    )
    release_hold_s: float = Field(
        default=_WARNING.release_hold_s,
        ge=0,
        le=60,
        description="the release rule's hold: a level stays on at least this long after it was last kept on, s",
    )
    release_hold_intervals: float = Field(
        default=_WARNING.release_hold_intervals,
        ge=0,
        le=10,
        description="and at least this many of the vehicle's update periods",
    )
    activation_speed_kmh: float = Field(
        default=_ENGINE.activation.activation_speed_kmh,
        ge=0,
        le=250,
        description="5.3.2: 0 activates the system on the vehicle's start, at any speed (a); a positive speed "
        "activates it when the vehicle reaches that speed, a standing vehicle then in standby (b)",
    )
    api_keys_file: Path | None = Field(
        default=None, description="the fleets' API keys (service.keys); without it the service answers anyone"
    )
    fcw_settings_file: Path | None = Field(
        default=None,
        description="the forward collision warning's settings per fleet (service.fcw_settings); without it each "
        "vehicle's category's",
    )
    warning_settings_file: Path | None = Field(
        default=None,
        description="the curve warning's update period and release rule per fleet (service.warning_settings); "
        "without it the service's for every fleet",
    )
    insecure: bool = Field(default=False, description="serve without API keys on an address other than loopback")
    max_body_bytes: int = Field(default=16 * 2**20, gt=0, description="the largest request body accepted, bytes")
    body_timeout_s: float = Field(default=10.0, gt=0, description="a client pausing this long in its body gets 408, s")
    head_timeout_s: float = Field(
        default=10.0, gt=0, description="a request head not complete this long after it may start gets 408, s"
    )
    public_docs: bool = Field(
        default=False, description="with API keys: /docs, /redoc, /openapi.json and /metrics open to all (else a key)"
    )

    mqtt: str = Field(
        default="",
        description="mqtt://HOST:PORT (or mqtts://): publish the events there (service.push.mqtt); empty: no MQTT",
    )
    webhooks_file: Path | None = Field(
        default=None,
        description="the fleets' webhooks (csws webhooks add); default: webhooks.json beside api_keys_file",
    )
    webhook_allow_private: bool = Field(
        default=False, description="webhooks may reach loopback and private addresses (never link-local, metadata)"
    )
    push_db: str = Field(
        default="",
        description="SQLite file of push's cursors, retries, dead letters and lease; default beside state_db",
    )

    @field_validator("mqtt")
    @classmethod
    def _mqtt_url(cls, value: str) -> str:
        from .push.mqtt import check_mqtt_url

        value = value.strip()
        return check_mqtt_url(value) if value else value

    @field_validator("event_retention_by_fleet")
    @classmethod
    def _fleet_names(cls, value: dict[str, float]) -> dict[str, float]:
        """Each fleet named as API keys name fleets (``service.keys.FLEET_PATTERN``), so that none is a typo that
        no key could ever match."""
        for fleet in value:
            if not FLEET_PATTERN.fullmatch(fleet):
                raise ValueError(f"not a fleet name: {fleet[:70]!r} (letters, digits, '_', '.', '-')")
        return value

    @field_validator("state")
    @classmethod
    def _redis_url(cls, value: str) -> str:
        value = value.strip()
        if value and urlsplit(value).scheme not in REDIS_SCHEMES:
            raise ValueError("give a Redis URL, redis://HOST:PORT/DB (or rediss:// or unix://), or nothing for SQLite")
        return value

    @field_validator("api_keys_file", "fcw_settings_file", "warning_settings_file", "webhooks_file", mode="before")
    @classmethod
    def _no_file(cls, value):
        return None if isinstance(value, str) and not value.strip() else value

    @model_validator(mode="after")
    def _keys_or_loopback(self) -> ServiceSettings:
        if self.api_keys_file is None and not self.insecure and not _is_loopback(self.host):
            raise ValueError(
                f"refusing to serve without API keys on {self.host}: give an API key file "
                f"(--api-keys FILE), listen on 127.0.0.1, or pass --insecure"
            )
        return self

    @model_validator(mode="after")
    def _shared_by_the_workers(self) -> ServiceSettings:
        if self.workers > 1 and not self.state and self.state_db.strip() in ("", ":memory:"):
            raise ValueError(
                f"an in-memory or temporary state database ({self.state_db!r}) is each worker's own: give "
                "--workers N a file (--state-db FILE) or a Redis (--state URL)"
            )
        return self

    @field_validator("nets", mode="before")
    @classmethod
    def _split_paths(cls, value):
        if isinstance(value, str):
            return [part for part in value.split(os.pathsep) if part]
        return value

    @model_validator(mode="after")
    def _networks_to_serve(self) -> ServiceSettings:
        """The networks given, else the bundled city; with ``test_tracks``, the bundled test tracks as well
        (alone when none are given)."""
        if self.test_tracks:
            given = {path.name for path in self.nets}
            self.nets = [*self.nets, *(path for path in track_network_paths() if path.name not in given)]
        elif not self.nets:
            self.nets = city_network_paths()
        return self

    def engine_settings(self) -> EngineSettings:
        """The library's engine settings with this service's latency of the updates and of the system."""
        warning = replace(
            _WARNING,
            update_period_s=self.update_period_s,
            system_delay_s=self.system_delay_s,
            learn_update_period=self.learn_update_period,
            max_update_period_s=self.max_update_period_s,
            release_margin_kmh=self.release_margin_kmh,
            release_hold_s=self.release_hold_s,
            release_hold_intervals=self.release_hold_intervals,
        )
        activation = replace(_ENGINE.activation, activation_speed_kmh=self.activation_speed_kmh)
        return replace(_ENGINE, warning=warning, activation=activation)

    def match_settings(self) -> MatchSettings:
        """The library's map matching settings with this service's tolerances and the sequence matcher's scales."""
        return replace(
            _MATCH,
            tolerance_m=self.match_tolerance_m,
            heading_tolerance_deg=self.heading_tolerance_deg,
            accuracy_m=self.match_accuracy_m,
            search_sigmas=self.match_search_sigmas,
            heading_sigma_deg=self.match_heading_sigma_deg,
            lane_change_log_p=self.match_lane_change_log_p,
            dead_reckoning_s=self.match_dead_reckoning_s,
            standstill_mps=self.match_standstill_mps,
            standstill_edge_log_p=self.match_standstill_edge_log_p,
            standstill_junction_log_p=self.match_standstill_junction_log_p,
        )


def _is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (127.0.0.0/8, ::1) or ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
