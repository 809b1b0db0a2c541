"""The README's library examples run as written and give the values their comments state."""

from __future__ import annotations

import ast
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
#: A number in a comment, with the decimals it is written to.
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def _python_blocks() -> list[str]:
    """The README's ```python blocks, in order."""
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def _stated_lines(block: str) -> list[tuple[str, str]]:
    """The expression lines of a block that end in a comment, with that comment's first line."""
    stated = []
    for line in block.splitlines():
        code, _, comment = line.partition("#")
        code = code.strip()
        if not comment or not code or line.startswith((" ", "from ", "import ")):
            continue
        try:
            ast.parse(code, mode="eval")
        except SyntaxError:
            continue  # an assignment: its comment explains, it states no value
        stated.append((code, comment.strip()))
    return stated


def _numbers_agree(shown: str, comment: str) -> bool:
    """Whether every number the comment states appears in ``shown`` rounded to the comment's decimals, in order."""
    shown_numbers = [float(n) for n in NUMBER.findall(shown)]
    for stated in NUMBER.findall(comment.split(" (")[0]):
        decimals = len(stated.partition(".")[2])
        matches = [i for i, value in enumerate(shown_numbers) if round(value, decimals) == float(stated)]
        if not matches:
            return False
        shown_numbers = shown_numbers[matches[0] + 1 :]
    return True


def test_the_library_examples_run_and_give_the_stated_values() -> None:
    namespace: dict = {}
    checked = 0
    for block in _python_blocks():
        stated = dict(_stated_lines(block))
        for statement in ast.parse(block).body:
            code = ast.get_source_segment(block, statement) or ""
            if isinstance(statement, ast.Expr) and code in stated:
                shown = repr(eval(compile(ast.Expression(statement.value), "README", "eval"), namespace))
                assert _numbers_agree(shown, stated[code]), (
                    f"README: {code} gives {shown}, the comment says {stated[code]}"
                )
                checked += 1
            else:
                exec(compile(ast.Module([statement], []), "README", "exec"), namespace)
    assert checked >= 6
