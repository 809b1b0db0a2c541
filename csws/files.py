"""Files the project writes whole: a reader sees the old file or the new one, never a part."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["replace_json"]


def replace_json(path: Path, content: Any) -> None:
    """Replace the file ``path`` at once with ``content`` as indented JSON, readable by its owner only.

    The JSON is written to a temporary file beside it (``mkstemp``: mode 0600), which then takes its
    name (``os.replace``, atomic on one file system); a failure leaves the old file and no temporary.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}-", suffix=".json")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as file:
            json.dump(content, file, indent=1, ensure_ascii=False)
            file.write("\n")
        os.replace(temporary, path)
    except OSError:
        Path(temporary).unlink(missing_ok=True)
        raise
