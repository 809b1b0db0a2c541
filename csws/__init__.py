"""csws: map-based curve speed warning for commercial vehicles, after T/ITS 0091-2018."""

__version__ = "0.1.0"
