"""Fleets and API keys: who may ask the service what, about which vehicles.

Every key belongs to one fleet and has a role:

* ``query``: warnings, horizons, curves, and reading its fleet's vehicles;
* ``admin``: all of that, and switching its fleet's vehicles on and off (5.2).

A fleet sees only its own vehicles: the same vehicle id in two fleets is two vehicles,
and a vehicle of another fleet does not exist for it (404). Keys travel as
``Authorization: Bearer KEY`` (:mod:`service.security` checks them).

The key file keeps no key, only the SHA-256 of each: keys are 256 random bits, so a plain
hash of one cannot be turned back into it, and a stolen file lets nobody in. Its format::

    {"format": "csws-api-keys/1",
     "keys": [{"fleet": "acme", "role": "admin", "sha256": "9f86d0...", "added": "2026-11-25T02:00:00Z",
               "label": "dispatch"}]}

``csws keys add FLEET --role ROLE --label LABEL --file FILE`` makes a key, adds its hash to the
file (created if missing, readable by its owner only) and prints the key once; ``csws keys list``
shows each key's fleet, label, role, date and fingerprint (the first digits of its hash, never the
key); ``csws keys revoke FINGERPRINT|LABEL`` takes a key out of the file and ``csws keys rotate
FINGERPRINT|LABEL`` puts a new key of the same fleet, role and label in its place. A running
service reads the file again when it changes (:class:`KeyRing`, every worker on its own), so
none of these needs a restart.
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path

from csws.files import read_json, replace_json

__all__ = [
    "KEYS_FORMAT",
    "Role",
    "Principal",
    "OPEN",
    "KeyRing",
    "KeyEntry",
    "add_key",
    "list_keys",
    "revoke_key",
    "rotate_key",
    "vehicle_key",
    "shown_id",
]

KEYS_FORMAT = "csws-api-keys/1"
#: Fleet names: letters, digits, ``_``, ``.`` and ``-`` (never ``/``, which joins a fleet to its vehicle ids).
FLEET_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")
#: Every key starts with this, so that a leaked one is recognisable.
KEY_PREFIX = "csws_"
#: Labels: 1-64 printable characters, no leading or trailing space.
LABEL_PATTERN = re.compile(r"[^\s\x00-\x1f\x7f](?:[^\x00-\x1f\x7f]{0,62}[^\s\x00-\x1f\x7f])?")
#: Hex digits of a key's hash that ``csws keys list`` shows as its fingerprint.
FINGERPRINT_DIGITS = 12
#: The fewest hex digits of a fingerprint that select a key (``csws keys revoke``).
MIN_FINGERPRINT_DIGITS = 6
#: A service looks at its key file's status (size, time, inode) at most this often, s: a key added,
#: revoked or rotated counts within this time, in every worker.
RELOAD_INTERVAL_S = 1.0


class Role(StrEnum):
    """What a key may do."""

    QUERY = "query"
    ADMIN = "admin"


@dataclass(frozen=True)
class Principal:
    """Who asks: a fleet and the role of its key. The fleet ``""`` is the service without keys."""

    fleet: str
    role: Role

    @property
    def may_switch(self) -> bool:
        """Whether it may switch vehicles on and off (5.2)."""
        return self.role is Role.ADMIN


#: Everyone, on a service without keys (loopback only, or ``--insecure``).
OPEN = Principal("", Role.ADMIN)


def vehicle_key(fleet: str, vehicle_id: str) -> str:
    """The vehicle as the service keeps it: its id within its fleet (fleet names have no ``/``)."""
    return f"{fleet}/{vehicle_id}" if fleet else vehicle_id


def shown_id(fleet: str, key: str) -> str:
    """The id ``fleet`` calls the vehicle kept as ``key`` (:func:`vehicle_key` undone)."""
    return key[len(fleet) + 1 :] if fleet else key


def _digest(key: str) -> str:
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


class KeyRing:
    """The fleets' keys, read from a key file, and read again when the file changes.

    At most every :data:`RELOAD_INTERVAL_S` a lookup checks the file's status (one ``stat``: its
    inode, size and modification time) and reads it again when that changed, so that keys added,
    revoked or rotated count in every worker without a restart. A file that has become unreadable
    or is no key file leaves the keys last read in force, and :attr:`reload_error` says why.

    Raises
    ------
    ValueError
        One line naming the file, when it cannot be read or is not a key file at start.
    """

    def __init__(self, path: str | Path, reload_interval_s: float = RELOAD_INTERVAL_S) -> None:
        self.path = Path(path)
        self.reload_interval_s = reload_interval_s
        self.reload_error: str | None = None
        self._status = _file_status(self.path)
        self._principals = _principals(_entries(self.path))
        self._checked_s = time.monotonic()

    def __len__(self) -> int:
        return len(self._principals)

    def principal(self, key: str) -> Principal | None:
        """The fleet and role of ``key``, None for a key that is not in the file (or was revoked)."""
        now_s = time.monotonic()
        if now_s - self._checked_s >= self.reload_interval_s:
            self._checked_s = now_s
            self.refresh()
        return self._principals.get(_digest(key))

    def refresh(self) -> bool:
        """Read the file again if its status changed since it was last read; whether the keys changed."""
        status = _file_status(self.path)
        if status == self._status:
            return False
        try:
            principals = _principals(_entries(self.path))
        except ValueError as exc:
            self.reload_error = str(exc)
            return False
        self._status, self._principals, self.reload_error = status, principals, None
        return True


def _file_status(path: Path) -> tuple[int, int, int, int] | None:
    """What tells a changed file: its device, inode, size and modification time (None when it is missing)."""
    try:
        status = os.stat(path)
    except OSError:
        return None
    return status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns


def _principals(entries: list[dict]) -> dict[str, Principal]:
    """The fleet and role of each key hash in a key file's entries."""
    return {entry["sha256"]: Principal(entry["fleet"], Role(entry["role"])) for entry in entries}


def _entries(path: Path) -> list[dict]:
    """The entries of a key file, checked; ValueError naming the file otherwise."""
    content = read_json(path, "an API key file")
    if (
        not isinstance(content, dict)
        or content.get("format") != KEYS_FORMAT
        or not isinstance(content.get("keys"), list)
    ):
        raise ValueError(f"{path}: not an API key file (expected format {KEYS_FORMAT!r})")
    for number, entry in enumerate(content["keys"], start=1):
        valid = (
            isinstance(entry, dict)
            and isinstance(entry.get("fleet"), str)
            and FLEET_PATTERN.fullmatch(entry["fleet"]) is not None
            and entry.get("role") in {role.value for role in Role}
            and isinstance(entry.get("sha256"), str)
            and re.fullmatch(r"[0-9a-f]{64}", entry["sha256"]) is not None
            and (entry.get("label") is None or _is_label(entry["label"]))
        )
        if not valid:
            raise ValueError(
                f"{path}: key {number} needs a fleet ({FLEET_PATTERN.pattern}), a role (query, admin) "
                f"and a sha256 of 64 hex digits (and, if labelled, a label of 1-64 printable characters)"
            )
    return content["keys"]


def _is_label(label: object) -> bool:
    """Whether ``label`` is a key's label: 1-64 printable characters, no space at either end."""
    return isinstance(label, str) and LABEL_PATTERN.fullmatch(label) is not None


@dataclass(frozen=True)
class KeyEntry:
    """One key of a key file as ``csws keys list`` shows it: everything but the key, which the file never has.

    Attributes
    ----------
    fingerprint
        The first :data:`FINGERPRINT_DIGITS` hex digits of the key's SHA-256.
    fleet, role, label
        Its fleet, role and label ("" without one).
    added
        When it was made (ISO 8601, UTC), "" when the file does not say.
    """

    fingerprint: str
    fleet: str
    role: Role
    label: str
    added: str


def _entry(entry: dict) -> KeyEntry:
    """A key file's entry as :class:`KeyEntry`."""
    return KeyEntry(
        entry["sha256"][:FINGERPRINT_DIGITS],
        entry["fleet"],
        Role(entry["role"]),
        entry.get("label") or "",
        entry.get("added") or "",
    )


def list_keys(path: str | Path) -> list[KeyEntry]:
    """The keys of a key file, in the file's order (ValueError for a file that is not a key file)."""
    return [_entry(entry) for entry in _entries(Path(path))]


def _now() -> str:
    """The time now, ISO 8601 in UTC to the second."""
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def _new_key() -> tuple[str, str]:
    """A new key and its SHA-256."""
    key = KEY_PREFIX + secrets.token_urlsafe(32)
    return key, _digest(key)


def _write(path: Path, entries: list[dict]) -> None:
    """Write a key file at once (a reader sees the old file or the new one), readable by its owner only."""
    replace_json(path, {"format": KEYS_FORMAT, "keys": entries})


def add_key(path: str | Path, fleet: str, role: Role | str, label: str = "") -> str:
    """Make a key for ``fleet`` with ``role`` (and ``label``), add its hash to the key file, and return the key.

    Raises
    ------
    ValueError
        For a bad fleet name, role or label, a label another key of the file has, or a file that is not a key file.
    """
    path = Path(path)
    if FLEET_PATTERN.fullmatch(fleet) is None:
        raise ValueError(f"fleet must be 1-64 letters, digits, '_', '.' or '-', got {fleet!r}")
    role = Role(role)
    if label and not _is_label(label):
        raise ValueError(f"a label is 1-64 printable characters without spaces at either end, got {label!r}")
    entries = _entries(path) if path.exists() else []
    if label and any(entry.get("label") == label for entry in entries):
        raise ValueError(f"{path}: a key labelled {label!r} is there already: labels name one key each")
    key, digest = _new_key()
    entry = {"fleet": fleet, "role": role.value, "sha256": digest, "added": _now()}
    _write(path, [*entries, {**entry, "label": label} if label else entry])
    return key


def _selected(path: Path, entries: list[dict], selector: str) -> int:
    """The index of the one entry that ``selector`` names: its label, or the start of its fingerprint.

    Raises
    ------
    ValueError
        When no key or several keys match.
    """
    digits = selector.lower()
    by_fingerprint = len(digits) >= MIN_FINGERPRINT_DIGITS and re.fullmatch(r"[0-9a-f]+", digits) is not None
    found = [
        index
        for index, entry in enumerate(entries)
        if entry.get("label") == selector or (by_fingerprint and entry["sha256"].startswith(digits))
    ]
    if not found:
        raise ValueError(
            f"{path}: no key has the label {selector!r} or a fingerprint starting with it "
            f"(a fingerprint needs at least {MIN_FINGERPRINT_DIGITS} hex digits; see csws keys list)"
        )
    if len(found) > 1:
        shown = ", ".join(entries[index]["sha256"][:FINGERPRINT_DIGITS] for index in found)
        raise ValueError(f"{path}: {selector!r} matches {len(found)} keys ({shown}): give more of a fingerprint")
    return found[0]


def revoke_key(path: str | Path, selector: str) -> KeyEntry:
    """Take the key that ``selector`` names (its label, or the start of its fingerprint) out of the key file.

    Raises
    ------
    ValueError
        For a file that is not a key file, or a selector that names no key or several.
    """
    path = Path(path)
    entries = _entries(path)
    index = _selected(path, entries, selector)
    revoked = entries.pop(index)
    _write(path, entries)
    return _entry(revoked)


def rotate_key(path: str | Path, selector: str) -> tuple[str, KeyEntry, KeyEntry]:
    """Replace the key that ``selector`` names by a new key of the same fleet, role and label.

    Returns
    -------
    tuple
        The new key (to show once), the entry revoked and the entry added.

    Raises
    ------
    ValueError
        For a file that is not a key file, or a selector that names no key or several.
    """
    path = Path(path)
    entries = _entries(path)
    index = _selected(path, entries, selector)
    old = entries[index]
    key, digest = _new_key()
    entries[index] = {**old, "sha256": digest, "added": _now()}
    _write(path, entries)
    return key, _entry(old), _entry(entries[index])
