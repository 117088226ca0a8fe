"""Student editions for the tests, built from this kit with the test run's one answer key.

The answer key (``hwtools/grade/answer_key.json``: the reference's values on the visible checks) is what
makes a build slow: ``write_answer_key`` runs the reference sandboxed, about 7 s on 2 cores and twice that
at load 4, and it is the same for every edition built from this kit. So a test run computes it once, in
its base temporary folder (``answer_key_file``), and ``build`` copies it into each edition it builds
(``build_student_edition`` without the key, then the copy: the same files as a build with the key).
``tests/instructor/test_release.py`` builds editions with the key the release writes itself, twice, and
checks the two are byte-identical; ``tests/instructor/test_student_path.py`` runs the release's command.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

KIT = Path(__file__).resolve().parents[2]


def answer_key_file(tmp_path_factory):
    """This kit's answer key, written by ``write_answer_key`` at the test run's first call."""
    path = tmp_path_factory.getbasetemp() / "answer_key.json"
    if not path.exists():
        from hwtools.grade import write_answer_key  # noqa: PLC0415

        building = Path(tempfile.mkdtemp(dir=path.parent)) / path.name
        write_answer_key(KIT, building)
        building.rename(path)  # complete or absent
    return path


def build(out, tmp_path_factory, **options):
    """``build_student_edition(KIT, out, **options)`` with the test run's answer key; returns ``out``."""
    from instructor.release import ANSWER_KEY, build_student_edition  # noqa: PLC0415

    build_student_edition(KIT, out, answer_key=False, **options)
    shutil.copyfile(answer_key_file(tmp_path_factory), Path(out) / ANSWER_KEY)
    return Path(out)
