"""The browser tests: JupyterLab in headless Chromium (``lab_under_test.py``). The day-one tests open the
student edition that ``tests/instructor/day_one.py`` builds."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "instructor"))
