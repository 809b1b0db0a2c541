"""The command line of one benchmark module.

Every ``python -m benchmarks.NAME`` takes ``--help`` (the module's docstring: what it measures and
how long it takes) and refuses an argument it does not know with one line and exit status 2, so
that asking for help never starts a run of several minutes nor ends in a traceback.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence

__all__ = ["arguments"]


def arguments(
    module_name: str,
    module_doc: str | None,
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
    argv: Sequence[str] | None = None,
) -> argparse.Namespace:
    """Parse a benchmark module's command line.

    Parameters
    ----------
    module_name
        The module's ``__name__`` or dotted name, e.g. ``"benchmarks.osm"``: the program name in usage lines.
    module_doc
        The module's docstring, shown by ``--help``.
    add_arguments
        Adds the module's own arguments to the parser; ``None`` for a module that takes none.
    argv
        The arguments; ``None`` reads ``sys.argv``.

    Returns
    -------
    argparse.Namespace
        The parsed arguments. A bad command line exits with status 2 and a usage line.
    """
    parser = argparse.ArgumentParser(
        prog=f"python -m {module_name.removesuffix('.__main__')}",
        description=(module_doc or "").strip(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    if add_arguments is not None:
        add_arguments(parser)
    return parser.parse_args(argv)
