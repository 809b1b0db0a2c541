"""``csws import-opendrive``: run the import and print what it wrote and noted."""

from __future__ import annotations

import argparse

from .importer import import_opendrive


def main(args: argparse.Namespace) -> int:
    """Import ``args.xodr`` into ``args.output`` and print a summary and the notes."""
    result = import_opendrive(args.xodr, args.output)
    print(f"read {args.xodr}: {result.roads} roads")
    print(f"wrote {result.net_path} ({result.convert_s:.1f} s in netconvert)")
    print(f"wrote {result.exact_path}: exact curvature of {result.exact_lanes} lanes")
    for note in result.notes:
        print(f"note: {note}")
    print(f"netconvert's messages: {result.log_path}")
    return 0
