"""csws: map-based curve speed warning for commercial vehicles, after T/ITS 0091-2018."""

from importlib.metadata import PackageNotFoundError, version

try:
    #: The installed distribution's version: pyproject.toml is its one source.
    __version__ = version("csws")
except PackageNotFoundError:  # a source tree on sys.path that was never installed
    __version__ = "0+unknown"
