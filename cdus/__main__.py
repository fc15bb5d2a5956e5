"""python -m cdus: the ``cdus`` command (cdus.app.cli)."""

import sys

from cdus.app.cli import main

sys.exit(main())
