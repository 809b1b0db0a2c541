"""Files the project writes whole: a reader sees the old file or the new one, never a part; and the caches
kept of such files, pruned to their own version's most recently used."""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

__all__ = ["prune_cache", "read_json", "replace_file", "replace_json"]


def replace_file(path: Path, write: Callable[[IO[bytes]], object], prefix: str, suffix: str) -> None:
    """Replace the file ``path`` at once with what ``write`` writes to a binary file, readable by its owner only.

    ``write`` writes to a temporary file beside it (``mkstemp`` with ``prefix`` and ``suffix``: mode 0600), which
    then takes its name (``os.replace``, atomic on one file system); a failure leaves the old file and no
    temporary.

    Raises
    ------
    OSError
        If the folder or the file cannot be written.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=prefix, suffix=suffix)
    try:
        with os.fdopen(handle, "wb") as file:
            write(file)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def replace_json(path: Path, content: Any) -> None:
    """Replace the file ``path`` at once with ``content`` as indented JSON, readable by its owner only
    (:func:`replace_file`)."""
    text = json.dumps(content, indent=1, ensure_ascii=False) + "\n"
    replace_file(path, lambda file: file.write(text.encode("utf-8")), f".{path.stem}-", ".json")


def read_json(path: Path, kind: str, error: type[Exception] = ValueError) -> Any:
    """The JSON content of the file ``path``; ``error`` with one line naming the file where it is missing,
    unreadable or not JSON. ``kind`` says what the file is, with its article, for that line ("an API key file")."""
    try:
        return json.loads(path.read_text("utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: no such file ({kind} expected)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{path}: not {kind} ({exc})") from None


def prune_cache(folder: Path, kind: str, suffix: str, version: str, kept: int, abandoned_s: float) -> None:
    """Remove the cache files ``{kind}-*{suffix}`` in ``folder`` of other versions than ``version`` (those not named
    ``{kind}-{version}-...``), all but the ``kept`` most recently used of its own, and the temporary files
    (``.{kind}-*{suffix}``, :func:`replace_file`) a writer abandoned more than ``abandoned_s`` ago."""
    own = []
    for cached in folder.glob(f"{kind}-*{suffix}"):
        if not cached.name.startswith(f"{kind}-{version}-"):
            _remove_quietly(cached)
            continue
        try:
            own.append((cached.stat().st_mtime, cached))
        except OSError:
            continue
    for _, old in sorted(own, reverse=True)[kept:]:
        _remove_quietly(old)
    for temporary in folder.glob(f".{kind}-*{suffix}"):
        try:
            abandoned = time.time() - temporary.stat().st_mtime > abandoned_s
        except OSError:
            continue
        if abandoned:
            _remove_quietly(temporary)


def _remove_quietly(path: Path) -> None:
    """Remove a file, if it can be: one that cannot (another user's, a read-only folder) stays."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass
