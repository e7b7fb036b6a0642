"""``python -m dashpot``: the ``dashpot`` command (:func:`dashpot.cli.main`)."""

import sys

from .cli import main

sys.exit(main())
