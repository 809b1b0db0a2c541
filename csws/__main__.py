"""``python -m csws``: the ``csws`` command."""

import sys

from csws.cli import main

sys.exit(main())
