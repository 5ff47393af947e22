"""``python -m hil``: the ``hil`` command, for an environment whose scripts directory is not on PATH."""

import sys

from hil.cli.main import main

sys.exit(main())
