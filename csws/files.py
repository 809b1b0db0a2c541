"""Files the project writes whole: a reader sees the old file or the new one, never a part."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

__all__ = ["replace_file", "replace_json"]


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
