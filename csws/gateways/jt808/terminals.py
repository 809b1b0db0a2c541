"""The terminals a fleet admits: phone number -> fleet, vehicle id, category, plate.

A JT/T 808 terminal names itself by the phone number of its SIM card. A terminal is admitted
when its number is in a fleet's list; it then speaks for one vehicle of that fleet, the same
vehicle the HTTP API calls ``vehicle_id``, with the same switch, category and session. The list
is a JSON file, managed like the API keys (``csws terminals add | list | revoke``)::

    {"format": "csws-jt808-terminals/1", "secret": "<64 hex digits>",
     "terminals": [{"phone": "13800138000", "fleet": "acme", "vehicle_id": "truck-18",
                    "category": "N", "plate": "京A12345", "generation": 1,
                    "added": "2026-11-26T02:00:00Z", "revoked": false}]}

The authentication code the platform hands out on registration (``0x8100``), and which the
terminal shows on every connection (``0x0102``), is an HMAC of the phone number and the
entry's generation under the file's secret: any gateway process with the file gives and checks
the same code without writing anything, a revoked terminal's code stops working at once, and
re-adding a number starts a new generation, so an old code does not come back.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from csws.errors import CswsError
from csws.files import read_json, replace_json
from csws.standard import Category

__all__ = [
    "TERMINALS_FORMAT",
    "NewTerminal",
    "Terminal",
    "TerminalError",
    "TerminalList",
    "add_terminal",
    "add_terminals",
    "revoke_terminal",
]

TERMINALS_FORMAT = "csws-jt808-terminals/1"
#: Fleet names as the API keys have them (no ``/``, which joins a fleet to its vehicle ids).
FLEET_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")
#: Vehicle ids as the HTTP API takes them: no ``/`` and no control characters, at most 64 characters.
VEHICLE_PATTERN = re.compile(r"[^/\x00-\x1f]{1,64}")
#: A phone number: up to 20 decimal digits (the 2019 edition's BCD[10]).
PHONE_PATTERN = re.compile(r"[0-9]{1,20}")


class TerminalError(CswsError, ValueError):
    """A terminal list that cannot be read or an entry that cannot be added."""


def phone_key(phone: str) -> str:
    """A phone number without the leading zeros its BCD field pads it with (6 bytes in 2013, 10 in 2019)."""
    return phone.lstrip("0") or "0"


@dataclass(frozen=True)
class Terminal:
    """One admitted terminal: the vehicle it speaks for."""

    phone: str
    fleet: str
    vehicle_id: str
    category: Category
    plate: str
    generation: int
    revoked: bool = False

    def speaks_as(self, phone: str) -> bool:
        """Whether a frame's header ``phone`` is this terminal's number (leading zeros ignored)."""
        return phone == self.phone or phone_key(phone) == phone_key(self.phone)


class TerminalList:
    """The admitted terminals, read from a terminal file, re-read when the file changes.

    Raises
    ------
    TerminalError
        One line naming the file, when it cannot be read or is not a terminal file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._path_name = os.fspath(self.path)
        self._stamp: tuple[int, int, int] | None = None
        self._load()

    def _load(self) -> None:
        stamp = _stamp(self.path)  # before the read: a file replaced meanwhile is read again at the next look
        content = _read(self.path)
        self._secret = bytes.fromhex(content["secret"])
        self._terminals = {phone_key(t.phone): t for t in map(_terminal, content["terminals"])}
        self._stamp = stamp

    def refresh(self) -> None:
        """Read the file again if it changed since it was read (revocations take effect at once).

        Raises
        ------
        TerminalError
            When the file is gone or cannot be read now (a hand edit half written): the terminals read last
            stay as they were.
        """
        try:
            if _stamp(self._path_name) != self._stamp:
                self._load()
        except OSError as exc:  # gone between the look and the read, or unreadable
            raise TerminalError(f"{self.path}: cannot be read ({exc.strerror or exc})") from None

    def terminal(self, phone: str) -> Terminal | None:
        """The terminal with ``phone`` (leading zeros ignored), revoked ones included; None if not listed."""
        return self._terminals.get(phone_key(phone))

    def auth_code(self, terminal: Terminal) -> str:
        """The authentication code of ``terminal``'s current generation."""
        message = f"{phone_key(terminal.phone)}:{terminal.generation}".encode()
        return hmac.new(self._secret, message, hashlib.sha256).hexdigest()[:24]

    def admitted(self, phone: str, auth_code: str) -> Terminal | None:
        """The terminal if ``phone`` is listed, not revoked, and ``auth_code`` is its code; None otherwise."""
        terminal = self.terminal(phone)
        if terminal is None or terminal.revoked:
            return None
        return terminal if hmac.compare_digest(auth_code, self.auth_code(terminal)) else None

    def __iter__(self) -> Iterator[Terminal]:
        return iter(self._terminals.values())


def _stamp(path: str | Path) -> tuple[int, int, int]:
    """What changes when the file is replaced or written: inode, size and modification time."""
    status = os.stat(path)
    return status.st_ino, status.st_size, status.st_mtime_ns


def _read(path: Path) -> dict[str, Any]:
    """The checked content of a terminal file; TerminalError naming the file otherwise."""
    content = read_json(path, "a terminal file", TerminalError)
    valid = (
        isinstance(content, dict)
        and content.get("format") == TERMINALS_FORMAT
        and isinstance(content.get("secret"), str)
        and re.fullmatch(r"[0-9a-f]{64}", content["secret"]) is not None
        and isinstance(content.get("terminals"), list)
    )
    if not valid:
        raise TerminalError(f"{path}: not a terminal file (expected format {TERMINALS_FORMAT!r} and a secret)")
    for number, entry in enumerate(content["terminals"], start=1):
        try:
            _terminal(entry)
        except (TypeError, KeyError, ValueError) as exc:
            raise TerminalError(f"{path}: terminal {number}: {exc}") from None
    return content


def _terminal(entry: dict[str, Any]) -> Terminal:
    """A file entry as a Terminal; ValueError naming the bad field."""
    checks = {
        "phone": PHONE_PATTERN,
        "fleet": FLEET_PATTERN,
        "vehicle_id": VEHICLE_PATTERN,
    }
    for name, pattern in checks.items():
        if not isinstance(entry.get(name), str) or pattern.fullmatch(entry[name]) is None:
            raise ValueError(f"bad {name} {entry.get(name)!r} (pattern {pattern.pattern})")
    generation = entry.get("generation")
    if not isinstance(generation, int) or generation < 1:
        raise ValueError(f"bad generation {generation!r} (a whole number from 1)")
    return Terminal(
        phone=entry["phone"],
        fleet=entry["fleet"],
        vehicle_id=entry["vehicle_id"],
        category=Category.parse(entry["category"]),
        plate=str(entry.get("plate", "")),
        generation=generation,
        revoked=bool(entry.get("revoked", False)),
    )


def _write(path: Path, content: dict[str, Any]) -> None:
    """Replace the file at once with ``content``, readable by its owner only."""
    replace_json(path, content)


@dataclass(frozen=True)
class NewTerminal:
    """A terminal to admit: its phone number, vehicle (default: the plate, else the phone number), category, plate."""

    phone: str
    category: str
    vehicle_id: str | None = None
    plate: str = ""


def add_terminals(path: str | Path, fleet: str, terminals: Sequence[NewTerminal]) -> list[Terminal]:
    """Admit ``terminals`` for vehicles of ``fleet``, in one write of the file (created if missing).

    A number already listed (revoked or not) is replaced by a new generation: codes handed out
    before stop working.

    Raises
    ------
    TerminalError
        For a bad fleet, phone, vehicle id or category, or a file that is not a terminal file.
    """
    path = Path(path)
    content: dict[str, Any] = (
        _read(path) if path.exists() else {"format": TERMINALS_FORMAT, "secret": secrets.token_hex(32)}
    )
    listed = {phone_key(entry["phone"]): entry for entry in content.get("terminals", [])}
    added = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    admitted = []
    for new in terminals:
        before = listed.get(phone_key(new.phone))
        entry = {
            "phone": new.phone,
            "fleet": fleet,
            "vehicle_id": new.vehicle_id or new.plate or phone_key(new.phone),
            "category": new.category,
            "plate": new.plate,
            "generation": before["generation"] + 1 if before else 1,
            "added": added,
            "revoked": False,
        }
        try:
            admitted.append(_terminal(entry))
        except ValueError as exc:
            raise TerminalError(f"terminal {new.phone!r}: {exc}") from None
        listed[phone_key(new.phone)] = entry
    _write(path, {**content, "terminals": list(listed.values())})
    return admitted


def add_terminal(
    path: str | Path, fleet: str, phone: str, *, vehicle_id: str | None = None, category: str, plate: str = ""
) -> Terminal:
    """Admit the terminal ``phone`` for ``fleet``'s vehicle (:func:`add_terminals` for one)."""
    [terminal] = add_terminals(path, fleet, [NewTerminal(phone, category, vehicle_id, plate)])
    return terminal


def revoke_terminal(path: str | Path, phone: str) -> Terminal:
    """Revoke the terminal ``phone``: it is refused from its next message on, by every gateway process.

    Raises
    ------
    TerminalError
        If the file cannot be read or does not list ``phone``.
    """
    path = Path(path)
    content = _read(path)
    for entry in content["terminals"]:
        if phone_key(entry["phone"]) == phone_key(phone):
            entry["revoked"] = True
            _write(path, content)
            return _terminal(entry)
    raise TerminalError(f"{path}: no terminal with phone number {phone}")
