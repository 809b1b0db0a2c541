"""What the service keeps of each vehicle between requests.

* The fleet's settings, the driver switch (5.2) and the category, survive a restart and
  are shared by the workers of one service: they are stored in SQLite (:class:`SettingStore`,
  WAL), and every request first reads them again if another worker has written since
  (:meth:`VehicleRegistry.refresh`).
* A session per vehicle seen recently: the network and lane of its last match, for
  the continuity of map matching, and its :class:`~csws.state.VehicleStatus`, which
  lives in the engine of that network. A vehicle that moves to another network takes
  its status along. Sessions idle for longer than the idle time expire and the engine
  forgets the vehicle, so memory stays bounded; its stored settings remain. Sessions are
  each worker's own.
"""

from __future__ import annotations

import sqlite3
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from csws.engine import Engine
from csws.mapmatch import MapPosition
from csws.standard import Category
from csws.state import VehicleStatus, switch

__all__ = ["VehicleSetting", "Session", "SettingStore", "StoreUnavailable", "VehicleRegistry"]

#: How long a write waits for a database another process holds locked, s: longer would hold
#: up every other request of the worker; the client is told to retry instead.
STORE_BUSY_TIMEOUT_S = 0.5


class StoreUnavailable(OSError):
    """The settings database cannot be written now (locked, unwritable, gone): retry later."""


@dataclass(frozen=True)
class VehicleSetting:
    """What a fleet set for a vehicle.

    Attributes
    ----------
    switched_on
        The CSWS switch (5.2).
    category
        The vehicle's category, used when a query gives none.
    """

    switched_on: bool = True
    category: Category | None = None


@dataclass
class Session:
    """A vehicle seen recently.

    Attributes
    ----------
    network_index
        The served network whose engine holds its status.
    lane_id
        Its last matched lane, None when the last fix matched nothing.
    last_seen_s
        When it was last queried, on the registry's clock, s.
    """

    network_index: int
    lane_id: str | None
    last_seen_s: float


class SettingStore:
    """Vehicle settings in SQLite, so that a restarted service keeps them.

    Parameters
    ----------
    path
        The database file (created with its folder if missing), or ``":memory:"``.
    """

    def __init__(self, path: str | Path) -> None:
        if str(path) != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        self.path = str(path)
        try:
            self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None,
                                       timeout=STORE_BUSY_TIMEOUT_S)  # fmt: skip
            if self.path != ":memory:":
                # Readers never wait for the writer: the workers of one service share the file.
                self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute(
                "CREATE TABLE IF NOT EXISTS vehicle_settings ("
                "vehicle_id TEXT PRIMARY KEY, switched_on INTEGER NOT NULL, category TEXT)"
            )
            self._version = self._data_version()
        except sqlite3.Error as exc:
            raise OSError(f"cannot open the vehicle settings database {path}: {exc}") from None

    def _data_version(self) -> int:
        return int(self._db.execute("PRAGMA data_version").fetchone()[0])

    def changed(self) -> bool:
        """Whether another connection (another worker of the service) has written to the
        database since the last call: SQLite's ``data_version``, one cheap query.

        Raises
        ------
        StoreUnavailable
            When the database cannot be read now.
        """
        try:
            version = self._data_version()
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle settings database {self.path} cannot be read now: {exc}") from None
        changed, self._version = version != self._version, version
        return changed

    def load(self) -> dict[str, VehicleSetting]:
        """Every stored setting.

        Raises
        ------
        OSError
            One line naming the file, when it is not a settings database of this service.
        """
        try:
            rows = self._db.execute("SELECT vehicle_id, switched_on, category FROM vehicle_settings").fetchall()
            return {
                vehicle_id: VehicleSetting(bool(on), Category(category) if category else None)
                for vehicle_id, on, category in rows
            }
        except (sqlite3.Error, ValueError) as exc:
            raise OSError(f"the vehicle settings database {self.path} cannot be read: {exc}") from None

    def save(self, vehicle_id: str, setting: VehicleSetting) -> None:
        """Store a vehicle's setting (replacing the previous one).

        Raises
        ------
        StoreUnavailable
            When the database cannot be written now; nothing was stored.
        """
        try:
            self._db.execute(
                "INSERT OR REPLACE INTO vehicle_settings (vehicle_id, switched_on, category) VALUES (?, ?, ?)",
                (vehicle_id, int(setting.switched_on), setting.category.value if setting.category else None),
            )
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle settings database {self.path} cannot be written now: {exc}") from None

    def close(self) -> None:
        """Close the database."""
        self._db.close()


class VehicleRegistry:
    """Sessions and settings of the vehicles, over the engines of the served networks.

    Parameters
    ----------
    engines
        One engine per served network, in the served order.
    store
        Where settings persist.
    idle_s
        A session not queried for this long expires, s.
    clock
        Seconds of a monotonic clock (injectable so that expiry is testable without waiting).
    """

    def __init__(
        self,
        engines: Sequence[Engine],
        store: SettingStore,
        idle_s: float,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not idle_s > 0:
            raise ValueError(f"the session idle time must be positive, got {idle_s!r} s")
        self.engines = tuple(engines)
        self.store = store
        self.idle_s = float(idle_s)
        self.clock = clock
        self.settings = store.load()
        self.sessions: OrderedDict[str, Session] = OrderedDict()

    def refresh(self) -> None:
        """Read the settings again when another worker changed them, and apply changed switches
        to the vehicles' sessions here: after a PUT through any worker, every later request
        through any worker sees it."""
        if not self.store.changed():
            return
        settings = self.store.load()
        for vehicle_id, session in self.sessions.items():
            setting = settings.get(vehicle_id)
            engine = self.engines[session.network_index]
            if setting is not None and setting.switched_on != engine.status(vehicle_id).switched_on:
                engine.switch(vehicle_id, setting.switched_on)
        self.settings = settings

    def expire(self) -> int:
        """End the sessions idle for longer than the idle time; return how many ended."""
        oldest_kept_s = self.clock() - self.idle_s
        ended = 0
        while self.sessions:
            vehicle_id, session = next(iter(self.sessions.items()))
            if session.last_seen_s >= oldest_kept_s:
                break
            self.sessions.popitem(last=False)
            self.engines[session.network_index].forget(vehicle_id)
            ended += 1
        return ended

    def previous(self, vehicle_id: str) -> MapPosition | None:
        """Where the vehicle was last matched, if it has a session and matched."""
        session = self.sessions.get(vehicle_id)
        if session is None or session.lane_id is None:
            return None
        return MapPosition(session.network_index, session.lane_id)

    def network_of(self, vehicle_id: str) -> int:
        """The network whose engine holds the vehicle's status (the first for a new vehicle)."""
        session = self.sessions.get(vehicle_id)
        return session.network_index if session is not None else 0

    def category(self, vehicle_id: str) -> Category | None:
        """The category the fleet set for the vehicle, if any."""
        setting = self.settings.get(vehicle_id)
        return setting.category if setting is not None else None

    def place(self, vehicle_id: str, network_index: int) -> None:
        """Make sure the vehicle has a session on ``network_index`` before its engine evaluates it.

        A new session starts from the stored switch; a vehicle that moved to another
        network takes its status along.
        """
        session = self.sessions.get(vehicle_id)
        if session is None:
            self.sessions[vehicle_id] = Session(network_index, None, self.clock())
            setting = self.settings.get(vehicle_id)
            if setting is not None and not setting.switched_on:
                self.engines[network_index].switch(vehicle_id, False)
        elif session.network_index != network_index:
            status = self.engines[session.network_index].status(vehicle_id)
            self.engines[session.network_index].forget(vehicle_id)
            self.engines[network_index].statuses[vehicle_id] = status
            session.network_index = network_index

    def seen(self, vehicle_id: str, lane_id: str | None) -> None:
        """Record that a vehicle (placed by :meth:`place`) was just seen, and its lane if it matched one.

        A fix that matched nothing keeps the last matched lane, so one bad fix does not
        break the continuity of the next.
        """
        session = self.sessions[vehicle_id]
        if lane_id is not None:
            session.lane_id = lane_id
        session.last_seen_s = self.clock()
        self.sessions.move_to_end(vehicle_id)

    def configure(self, vehicle_id: str, switched_on: bool, category: Category | None) -> VehicleStatus:
        """Set and store a vehicle's switch (5.2) and category; return its status."""
        previous = self.settings.get(vehicle_id, VehicleSetting())
        setting = VehicleSetting(switched_on, category if category is not None else previous.category)
        self.store.save(vehicle_id, setting)
        self.settings[vehicle_id] = setting
        network_index = self.network_of(vehicle_id)
        self.place(vehicle_id, network_index)
        self.seen(vehicle_id, None)
        return self.engines[network_index].switch(vehicle_id, switched_on)

    def known(self, vehicle_id: str) -> bool:
        """Whether the vehicle has a session or stored settings."""
        return vehicle_id in self.sessions or vehicle_id in self.settings

    def status(self, vehicle_id: str) -> VehicleStatus:
        """The vehicle's status: from its engine, or the stored switch when it has no session."""
        session = self.sessions.get(vehicle_id)
        if session is not None:
            return self.engines[session.network_index].status(vehicle_id)
        setting = self.settings.get(vehicle_id, VehicleSetting())
        return switch(VehicleStatus(), setting.switched_on)
