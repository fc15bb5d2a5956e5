"""What does ``python -m cdus`` run? The ``cdus`` command (cdus.app.cli)."""

import sys

from cdus.app.cli import main

sys.exit(main())
