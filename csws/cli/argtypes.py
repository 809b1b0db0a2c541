"""Argument types for the ``csws`` subcommands: each checks one kind of value and says what is wrong.

argparse turns the ``ArgumentTypeError`` into one line naming the option, and exit status 2.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

__all__ = ["positive_int", "positive_float", "step_length", "comma_list", "one_of", "key_file"]

T = TypeVar("T")


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1: {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive finite number: {text!r}")
    return value


def step_length(text: str) -> float:
    """A SUMO step length in s: a multiple of 1 ms (SUMO's resolution) in (0, 1]."""
    value = positive_float(text)
    if value > 1 or abs(value * 1000 - round(value * 1000)) > 1e-9:
        raise argparse.ArgumentTypeError(f"a step length must be a multiple of 0.001 s in (0, 1]: {text!r}")
    return value


def comma_list(item: Callable[[str], T], what: str = "value") -> Callable[[str], list[T]]:
    """A type for comma-separated values, each checked by ``item``; at least one is required."""

    def parse(text: str) -> list[T]:
        parts = [part.strip() for part in text.split(",") if part.strip()]
        if not parts:
            raise argparse.ArgumentTypeError(f"give at least one {what}, comma-separated")
        return [item(part) for part in parts]

    return parse


def one_of(choices: tuple[str, ...], normalise: Callable[[str], str] = str) -> Callable[[str], str]:
    """A type for one value among ``choices`` (after ``normalise``, e.g. ``str.upper``)."""

    def parse(text: str) -> str:
        value = normalise(text)
        if value not in choices:
            raise argparse.ArgumentTypeError(f"{text!r} is not one of {', '.join(choices)}")
        return value

    return parse


def output_folder(text: str) -> Path:
    """A folder to write into: made when missing; a file of that name is refused."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder: give a folder (made if missing)")
    return path


def network_file(text: str) -> Path:
    """A SUMO network to write: the name must end in ``.net.xml`` or ``.net.xml.gz``, so
    that the files written beside it (curve index, log) are named after it."""
    if not text.endswith((".net.xml", ".net.xml.gz")) or Path(text).name in (".net.xml", ".net.xml.gz"):
        raise argparse.ArgumentTypeError(f"{text!r} is no network name: give NAME.net.xml or NAME.net.xml.gz")
    return Path(text)


def key_file(text: str) -> str:
    """The API key kept in the file ``text``: its first line, without surrounding blanks."""
    try:
        lines = Path(text).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise argparse.ArgumentTypeError(
            f"cannot read the key file {text!r}: {getattr(exc, 'strerror', None) or exc}"
        ) from None
    key = lines[0].strip() if lines else ""
    if not key:
        raise argparse.ArgumentTypeError(
            f"the key file {text!r} is empty: put the key (csws keys add) on its first line"
        )
    return key
