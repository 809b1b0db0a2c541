"""``csws keys add | list | revoke | rotate``: manage the fleets' key file (:mod:`service.keys`).

A new key is printed once, on stdout and alone on its line (for a script to keep); everything else
goes to stderr. No command ever prints a key it did not just make: the file has none, only hashes.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from .keys import KeyEntry, add_key, list_keys, revoke_key, rotate_key

__all__ = ["key_file", "add_command", "list_command", "revoke_command", "rotate_command", "key_table"]


def key_file(args: argparse.Namespace) -> Path:
    """The key file of a ``csws keys`` command: ``--file``, else ``$CSWS_API_KEYS_FILE``."""
    path = args.file or os.environ.get("CSWS_API_KEYS_FILE")
    if not path:
        raise ValueError("give the key file: --file FILE, or set CSWS_API_KEYS_FILE")
    return Path(path)


def _described(entry: KeyEntry) -> str:
    """A key in words, for the messages: its fingerprint, fleet, role and label."""
    label = f", label {entry.label!r}" if entry.label else ""
    return f"{entry.fingerprint} (fleet {entry.fleet!r}, role {entry.role.value}{label})"


def add_command(args: argparse.Namespace) -> int:
    """``csws keys add``: a new key for a fleet, printed once; its hash goes into the key file."""
    path = key_file(args)
    key = add_key(path, args.fleet, args.role, args.label or "")
    print(key)
    count = len(list_keys(path))
    print(
        f"csws: added a key of fleet {args.fleet!r} with role {args.role} to {path} ({count} keys in all); "
        "the key is shown only this once",
        file=sys.stderr,
    )
    return 0


def key_table(entries: list[KeyEntry]) -> str:
    """The keys as an aligned table: fingerprint, fleet, role, label, added (never a key)."""
    rows = [("FINGERPRINT", "FLEET", "ROLE", "LABEL", "ADDED")]
    rows += [(e.fingerprint, e.fleet, e.role.value, e.label or "-", e.added or "-") for e in entries]
    widths = [max(len(row[column]) for row in rows) for column in range(len(rows[0]))]
    return "\n".join(
        "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip() for row in rows
    )


def list_command(args: argparse.Namespace) -> int:
    """``csws keys list``: the keys of the key file, one a line, by fingerprint (never the key)."""
    print(key_table(list_keys(key_file(args))))
    return 0


def revoke_command(args: argparse.Namespace) -> int:
    """``csws keys revoke``: take a key out of the key file; a running service stops taking it within a second."""
    path = key_file(args)
    revoked = revoke_key(path, args.key)
    print(f"csws: revoked {_described(revoked)} in {path}", file=sys.stderr)
    return 0


def rotate_command(args: argparse.Namespace) -> int:
    """``csws keys rotate``: a new key in place of an old one (same fleet, role, label), printed once."""
    path = key_file(args)
    key, old, new = rotate_key(path, args.key)
    print(key)
    print(
        f"csws: {_described(new)} replaces {old.fingerprint} in {path}, which is revoked; "
        "the new key is shown only this once",
        file=sys.stderr,
    )
    return 0
