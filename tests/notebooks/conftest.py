"""The report's tests run the report in a student edition that ``tests/instructor/editions.py`` builds."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "instructor"))
