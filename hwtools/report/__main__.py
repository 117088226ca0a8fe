"""``python -m hwtools.report OUT_DIR [--name "NAME / ANDREW ID"] [--no-pdf]``: see ``hwtools.report``."""

import sys

from hwtools.report.command import main

sys.exit(main())
