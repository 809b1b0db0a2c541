"""Data the package ships: the standard's tables as transcribed (T/ITS 0091-2018, Tables 1-9)."""

import json
from functools import cache
from importlib.resources import files


@cache
def standard_tables() -> dict:
    """Tables 1-9 of T/ITS 0091-2018 as transcribed, with the transcription's notes."""
    return json.loads(files(__package__).joinpath("t_its_0091_2018_tables.json").read_text("utf-8"))
