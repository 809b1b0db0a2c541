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
     "keys": [{"fleet": "acme", "role": "admin", "sha256": "9f86d0...", "added": "2026-11-25T02:00:00Z"}]}

``csws keys add FLEET --role ROLE --file FILE`` makes a key, adds its hash to the file
(created if missing, readable by its owner only) and prints the key once.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import tempfile
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path

__all__ = [
    "KEYS_FORMAT",
    "Role",
    "Principal",
    "OPEN",
    "KeyRing",
    "add_key",
    "vehicle_key",
    "shown_id",
]

KEYS_FORMAT = "csws-api-keys/1"
#: Fleet names: letters, digits, ``_``, ``.`` and ``-`` (never ``/``, which joins a fleet to its vehicle ids).
FLEET_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")
#: Every key starts with this, so that a leaked one is recognisable.
KEY_PREFIX = "csws_"


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
    """The fleets' keys, read from a key file.

    Raises
    ------
    ValueError
        One line naming the file, when it cannot be read or is not a key file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._principals = {
            entry["sha256"]: Principal(entry["fleet"], Role(entry["role"])) for entry in _entries(self.path)
        }

    def __len__(self) -> int:
        return len(self._principals)

    def principal(self, key: str) -> Principal | None:
        """The fleet and role of ``key``, None for a key that is not in the file."""
        return self._principals.get(_digest(key))


def _entries(path: Path) -> list[dict]:
    """The entries of a key file, checked; ValueError naming the file otherwise."""
    try:
        content = json.loads(path.read_text("utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: no such API key file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not an API key file ({exc})") from None
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
        )
        if not valid:
            raise ValueError(
                f"{path}: key {number} needs a fleet ({FLEET_PATTERN.pattern}), a role (query, admin) "
                f"and a sha256 of 64 hex digits"
            )
    return content["keys"]


def add_key(path: str | Path, fleet: str, role: Role | str) -> str:
    """Make a key for ``fleet`` with ``role``, add its hash to the key file, and return the key.

    Raises
    ------
    ValueError
        For a bad fleet name or role, or a file that is not a key file.
    """
    path = Path(path)
    if FLEET_PATTERN.fullmatch(fleet) is None:
        raise ValueError(f"fleet must be 1-64 letters, digits, '_', '.' or '-', got {fleet!r}")
    role = Role(role)
    entries = _entries(path) if path.exists() else []
    key = KEY_PREFIX + secrets.token_urlsafe(32)
    added = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    entries.append({"fleet": fleet, "role": role.value, "sha256": _digest(key), "added": added})
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".api-keys-", suffix=".json")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as file:
            json.dump({"format": KEYS_FORMAT, "keys": entries}, file, indent=1)
            file.write("\n")
        os.replace(temporary, path)
    except OSError:
        Path(temporary).unlink(missing_ok=True)
        raise
    return key
