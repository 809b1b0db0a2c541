"""Progress of long runs when stderr is no terminal: a line every tenth of the way, amounts without float noise."""

from __future__ import annotations

import io

from csws.cli.progress import Progress


def test_a_known_total_prints_a_line_every_tenth_of_the_way():
    stream = io.StringIO()
    progress = Progress("conformance", 185, "tasks", stream=stream)
    for _ in range(185):
        progress.update()
    progress.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 10
    assert lines[0] == "csws conformance: 19 of 185 tasks (10 %)"
    assert lines[-1] == "csws conformance: 185 of 185 tasks (100 %)"


def test_float_steps_print_rounded_amounts():
    stream = io.StringIO()
    progress = Progress("cosim", 377.2, "sim s", decimals=1, stream=stream)
    for _ in range(3772):
        progress.update(0.1)
    text = stream.getvalue()
    assert "csws cosim: 377.2 of 377.2 sim s (100 %)" in text
    assert "0000000" not in text


def test_a_library_call_shows_nothing():
    stream = io.StringIO()
    progress = Progress("cosim", 10.0, "sim s", enabled=False, stream=stream)
    progress.update(10.0)
    progress.close()
    assert stream.getvalue() == ""


def test_a_resumed_run_counts_from_what_was_done_and_says_the_time_left():
    stream = io.StringIO()
    progress = Progress("sweep", 10, "runs", stream=stream, done=4, time_left=True)
    for _ in range(6):
        progress.update()
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("csws sweep: 5 of 10 runs (50 %), about ") and lines[0].endswith(" s left")
    assert lines[-1] == "csws sweep: 10 of 10 runs (100 %)"
    assert len(lines) == 6
