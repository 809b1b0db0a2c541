"""Settings files a service reads at start-up: a JSON object that names its format (``{"format": "csws-…/1", …}``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from csws.files import read_json

__all__ = ["read_settings_file"]


def read_settings_file(path: Path, format_name: str, kind: str) -> dict[str, Any]:
    """The JSON object of the settings file at ``path``, which names ``format_name`` as its format.

    Parameters
    ----------
    path
        The file.
    format_name
        Its ``format`` field, e.g. ``csws-fcw-settings/1``.
    kind
        What it is, with its article, for the messages: ``an FCW settings file``.

    Raises
    ------
    ValueError
        One line naming the file: missing, unreadable, not JSON, not an object, or another format.
    """
    content = read_json(path, kind)
    if not isinstance(content, dict) or content.get("format") != format_name:
        raise ValueError(f"{path}: not {kind} (expected format {format_name!r})")
    return content
