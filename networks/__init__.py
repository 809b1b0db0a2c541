"""The SUMO networks csws ships: the test tracks of T/ITS 0091-2018, their generator and truth.

Installed as the package ``csws.networks`` so that the networks are there right after
``pip install``; in a source checkout this is the top-level ``networks/`` folder.
"""

from importlib.resources import files
from pathlib import Path


def networks_dir() -> Path:
    """The folder of the bundled networks."""
    return Path(str(files(__package__)))
