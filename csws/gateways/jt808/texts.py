"""What the gateway tells the driver through the terminal (``0x8300``): text shown and spoken.

5.5.1: the two warning levels must differ clearly, and the warning must stand apart from other
indications; 5.5.2: the switched-off state visible; 5.5.3: a fault clearly shown. The gateway
speaks only when the indication changes: a level comes on or rises, the system is switched off
or faults, or it comes back. Each fleet may word the texts itself (a JSON file of
:class:`DriverTexts` fields per fleet); ``{speed_kmh}`` in a warning text is replaced by the
warning speed V_w of the curve, rounded down to whole km/h.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import NamedTuple

from csws.errors import CswsError

__all__ = [
    "FAULT_CONFIRM_S",
    "Announcer",
    "DriverTexts",
    "Indication",
    "TextsError",
    "indication",
    "load_fleet_texts",
    "text_of",
]


#: A fault is told once it has lasted this long, s (5.5.3): a report that matches no road, or one that
#: came too late, is not a fault of the system the driver must hear about; one that lasts is.
FAULT_CONFIRM_S = 10.0


class TextsError(CswsError, ValueError):
    """A texts file that cannot be read."""


@dataclass(frozen=True)
class DriverTexts:
    """The words of each indication; ``{speed_kmh}`` stands for V_w in the warning texts."""

    level1: str = "前方弯道，请减速，建议车速{speed_kmh}公里"
    level2: str = "弯道超速，立即减速！建议车速{speed_kmh}公里"
    switched_off: str = "弯道预警已关闭"
    fault: str = "弯道预警故障，请注意"
    restored: str = "弯道预警已恢复"


class Indication(NamedTuple):
    """What the driver is being told: a warning level (0-2), or that the system is off or faulty (a named tuple:
    one is made for every answer)."""

    level: int
    state: str

    @property
    def kind(self) -> str:
        """``level1``, ``level2``, ``switched_off``, ``fault`` or ``quiet`` (active or standby, no warning)."""
        if self.state == "fault":
            return "fault"
        if self.state == "off":
            return "switched_off"
        return f"level{self.level}" if self.level else "quiet"


def indication(state: str, level: int) -> Indication:
    """The indication of an answer's system state and level."""
    return Indication(level=level if state in ("active", "standby") else 0, state=state)


def text_of(
    texts: DriverTexts, before: Indication | None, now: Indication, warning_speed_kmh: float | None
) -> str | None:
    """What to say when the indication goes from ``before`` to ``now``; None when nothing is to be said.

    A warning is said when its level comes on or rises (6.2.1: level 2 has priority); off and
    fault when the system enters them; "restored" when it leaves them. A level that falls or
    ends is not said (the display clears with the next level or on its own).
    """
    if before is not None and before.kind == now.kind:
        return None
    if now.kind in ("level1", "level2"):
        if before is not None and before.kind == "level2" and now.kind == "level1":
            return None
        speed = "" if warning_speed_kmh is None else str(math.floor(warning_speed_kmh))
        return getattr(texts, now.kind).replace("{speed_kmh}", speed)
    if now.kind in ("switched_off", "fault"):
        return getattr(texts, now.kind)
    if before is not None and before.kind in ("switched_off", "fault"):
        return texts.restored
    return None


def _fits(text: object) -> bool:
    """Whether ``text`` is a string GBK can write in at most 1,000 bytes (a 0x8300 body holds 1,023)."""
    try:
        return isinstance(text, str) and len(text.encode("gbk")) <= 1000
    except UnicodeEncodeError:
        return False


class Announcer:
    """What one driver has been told, and what to tell next (:func:`text_of`), a fault only once confirmed.

    Parameters
    ----------
    texts
        The driver's fleet's texts.
    """

    def __init__(self, texts: DriverTexts) -> None:
        self.texts = texts
        self.told: Indication | None = None
        self.fault_since_s: float | None = None

    def update(self, state: str, level: int, warning_speed_kmh: float | None, time_s: float) -> tuple[str, bool] | None:
        """The text to tell (and whether it is urgent: level 2 or a fault) for an answer at ``time_s``; None for none.

        A fault shorter than :data:`FAULT_CONFIRM_S` leaves the driver's indication as it was.
        """
        now = indication(state, level)
        if now == self.told and state != "fault":  # most answers: the same as told before, nothing to say
            self.fault_since_s = None
            return None
        if now.kind == "fault":
            self.fault_since_s = time_s if self.fault_since_s is None else self.fault_since_s
            if time_s - self.fault_since_s < FAULT_CONFIRM_S:
                return None
        else:
            self.fault_since_s = None
        text = text_of(self.texts, self.told, now, warning_speed_kmh)
        self.told = now
        return None if text is None else (text, now.kind in ("level2", "fault"))


def load_fleet_texts(path: str | Path) -> dict[str, DriverTexts]:
    """Each fleet's texts from a JSON file ``{"FLEET": {"level1": "...", ...}}``; missing ones keep the defaults.

    Raises
    ------
    TextsError
        One line naming the file and the problem.
    """
    names = {field.name for field in fields(DriverTexts)}
    try:
        content = json.loads(Path(path).read_text("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise TextsError(f"{path}: not a texts file ({exc})") from None
    if not isinstance(content, dict) or not all(isinstance(v, dict) for v in content.values()):
        raise TextsError(f"{path}: expected {{fleet: {{text name: text}}}}")
    result = {}
    for fleet, texts in content.items():
        unknown = set(texts) - names
        if unknown or not all(_fits(v) for v in texts.values()):
            raise TextsError(f"{path}: fleet {fleet!r}: texts are {sorted(names)}, strings of at most 1,000 GBK bytes")
        result[fleet] = DriverTexts(**texts)
    return result
