"""The API fuzzing of ``tests/test_fuzz.py`` at a larger scale than the CI's: more cases per operation,
more and longer sequences along the schema's links.

It runs that test module with pytest, its bounds raised through the environment
(``CSWS_FUZZ_MAX_EXAMPLES``, ``CSWS_FUZZ_SEQUENCES``, ``CSWS_FUZZ_STEPS``), against the same real
service on loopback with API keys. Figures: whether every test passed (no 5xx, every answer as
documented) and how long the run took.

Run with ``python -m benchmarks.fuzz [MAX_EXAMPLES [SEQUENCES [STEPS]]]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.command import arguments

MAX_EXAMPLES = 500
SEQUENCES = 300
STEPS = 12


def run(max_examples: int = MAX_EXAMPLES, sequences: int = SEQUENCES, steps: int = STEPS) -> dict:
    """Run the fuzzing tests with these bounds; whether they passed, the tail of pytest's report, the time."""
    root = Path(__file__).resolve().parents[1]
    env = {
        **os.environ,
        "CSWS_FUZZ_MAX_EXAMPLES": str(max_examples),
        "CSWS_FUZZ_SEQUENCES": str(sequences),
        "CSWS_FUZZ_STEPS": str(steps),
    }
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_fuzz.py"],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
    )
    return {
        "max_examples": max_examples,
        "sequences": sequences,
        "steps": steps,
        "passed": done.returncode == 0,
        "report": done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr[-300:],
        "run_s": round(time.perf_counter() - started, 1),
    }


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The three optional bounds of the fuzzing run, in order."""
    parser.add_argument("max_examples", type=int, nargs="?", default=MAX_EXAMPLES, help="examples per operation")
    parser.add_argument("sequences", type=int, nargs="?", default=SEQUENCES, help="stateful sequences")
    parser.add_argument("steps", type=int, nargs="?", default=STEPS, help="steps per stateful sequence")


def main() -> None:
    """Print each figure."""
    given = arguments("benchmarks.fuzz", __doc__, _add_arguments)
    for name, value in run(given.max_examples, given.sequences, given.steps).items():
        print(f"{name:>14}: {value}")


if __name__ == "__main__":
    main()
