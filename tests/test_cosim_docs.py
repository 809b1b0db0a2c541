"""docs/cosim.md's Python runs as written, with what csws installs: every ``python`` block, in order, in
one namespace, in a fresh folder (the first block makes the short run the others read)."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "cosim.md"


def _python_blocks(markdown: str) -> list[str]:
    """The code of every fenced ``python`` block, in order."""
    return re.findall(r"^```python\n(.*?)^```$", markdown, flags=re.DOTALL | re.MULTILINE)


def test_the_docs_have_python_to_run() -> None:
    blocks = _python_blocks(DOC.read_text())
    assert len(blocks) >= 4
    assert not any(re.search(r"^\s*(import|from)\s+pandas\b", block, flags=re.MULTILINE) for block in blocks)


@pytest.mark.slow
@pytest.mark.sumo
def test_every_python_block_of_the_docs_runs(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "cosim_docs"}
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        for number, block in enumerate(_python_blocks(DOC.read_text()), start=1):
            exec(compile(block, f"{DOC.name} python block {number}", "exec"), namespace)
    output = printed.getvalue()
    assert output.startswith("complete {'level1': ")
    assert "vehicles warned" in output and "km/h above V_w" in output
    assert "vehicle-steps by curve warning level: {" in output
