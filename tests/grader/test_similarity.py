"""The similarity report per TODO (``hwtools/grade/instructor/similarity.py``): planted copies found,
independent solutions left alone, a page that escapes what students wrote, nothing sent anywhere.

The class is ``similarity_class.make_class``'s (students who write each TODO their own way, copiers
who disguise a whole submission by renaming, reordering, commenting or changing a constant), smaller
than ``benchmarks/bench_similarity.py``'s class of 150 so that the suite stays quick.
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys
from pathlib import Path

import pytest

import similarity_class
from hwtools.grade import blocks, kits
from hwtools.grade.instructor import similarity

KIT = Path(__file__).resolve().parents[2]
pytestmark = [pytest.mark.timeout(300)]
STUDENTS, COPIES, SEED = 48, 4, 8  # one copier of each kind; 2.2.1: a short block, a constant changed; 2.3.1: the handout


@pytest.fixture(scope="module")
def layout():
    return blocks.load_layout(KIT)


@pytest.fixture(scope="module")
def planted_class(layout, tmp_path_factory):
    folder = tmp_path_factory.mktemp("similarity") / "class"
    planted = similarity_class.make_class(layout, folder, STUDENTS, COPIES, SEED)
    return folder, planted, similarity.similarity(folder, layout)


def test_the_planted_copies_are_the_top_pairs_of_every_todo_and_flagged(layout, planted_class):
    """Every TODO's 10 best pairs hold at least 90% of the planted copies it can show (those where neither
    block is only the handout's equations: ``similarity_class.handout_only``); a pair the report lists as
    no evidence has such a block."""
    folder, planted, report = planted_class
    assert sorted(planted.values()) == sorted(similarity_class.COPY_KINDS)
    recall = similarity_class.recall(report, planted, layout)
    coded = [todo for todo in recall if todo not in report.silent]
    assert len(coded) >= 8 and set(report.silent) <= {"1.3.3"}, report.silent  # 1.3.3 is one constant
    assert min(recall[todo] for todo in coded) >= 0.9, recall
    only = similarity_class.handout_only(report, {pair.students: "" for found in report.handout_only.values()
                                                  for pair in found}, layout)
    assert all(pair.students in only[todo] for todo, found in report.handout_only.items() for pair in found)
    flagged = {pair.students for found in report.pairs.values() for pair in found if pair.flagged}
    assert set(planted) <= flagged, "every copier is flagged in some TODO"
    independent = [pair for found in report.pairs.values() for pair in found if pair.flagged and pair.students not in planted]
    pairs = STUDENTS * (STUDENTS - 1) // 2 * len(coded)
    assert len(independent) <= 0.005 * pairs, [(pair.todo, pair.students, round(pair.score, 2)) for pair in independent]


def test_independently_written_natural_solutions_are_at_most_five_percent_flagged(layout, tmp_path):
    """The kit's natural solutions (``natural_solutions/``: one way each to write a TODO, by hand), each
    a submission of its own (``similarity_class.natural_class``), all compared: at most 5% of the pairs of
    one TODO's solutions flagged."""
    pairs = similarity_class.natural_class(layout, tmp_path)
    report = similarity.similarity(tmp_path, layout)
    flagged = [(pair.todo, pair.students, round(pair.score, 2)) for found in report.pairs.values() for pair in found
               if pair.flagged]
    assert pairs >= 60 and len(flagged) <= 0.05 * pairs, flagged
    assert all(first.split("_")[0] == second.split("_")[0] == todo for todo, (first, second), _ in flagged)


SCRIPT = "</pre><script>alert(document.cookie)</script>"
COPIED = ("for i in range(len(x)):\n    step = np.zeros_like(x)\n    step[i] = h[i]  # " + SCRIPT + "\n"
          "    s = ' " + SCRIPT + " '\n    gradient[i] = (f(x + step) - f(x - step)) / (2.0 * h[i])\n")


HANDOUT = {"2.3.1": "mine = (y == c).astype(int)\nself.classifiers[c].gradient_ascent_step(X, mine, learning_rate)"}
OWN = "self.classifiers[c].gradient_ascent_step(X, np.where(y == c, 1, 0), learning_rate)"


def small_class(layout, folder):
    """Two students who hand in one block (with markup in it) and 2.3.1 as the handout writes it, and two
    who write their own; a damaged zip."""
    for student, bodies in (("<b>bo", {"1.2.1": COPIED, **HANDOUT}), ("=cmd|' -C calc'!A0", {"1.2.1": COPIED, **HANDOUT}),
                            ("ana", {"1.2.1": "gradient[:] = 0", "2.3.1": OWN}),
                            ("dee", {"1.2.1": "gradient = np.array([1.0 for _ in x])"})):
        kits.write_submission(layout, folder / student, bodies)
    (folder / "broken.zip").write_bytes(b"PK\x03\x04" + bytes(50))
    return folder


def test_the_csv_ranks_each_todo_and_the_page_escapes_what_students_wrote(layout, tmp_path):
    report = similarity.write_report(small_class(layout, tmp_path / "class"), tmp_path / "out", layout)
    table, page = similarity.report_paths(tmp_path / "out")
    text = page.read_text(encoding="utf-8")
    assert "<script>" not in text and "<b>" not in text and "&lt;script&gt;" in text and "&lt;b&gt;bo" in text
    assert "broken" in report.unread and "broken" in text and "<mark>" in text
    rows = list(csv.reader(io.StringIO(table.read_text(encoding="utf-8"))))
    assert tuple(rows[0]) == similarity.CSV_HEADER
    ranked = [row for row in rows[1:] if row[0] == "1.2.1"]
    assert [(row[1], row[2], row[3], row[9]) for row in ranked] == [("1", "<b>bo", "'=cmd|' -C calc'!A0", "yes")]
    # 2.3.1, the handout's equations in both: listed once, as no evidence, not ranked
    assert [(row[1], row[2], row[3], row[9], row[10]) for row in rows if row[0] == "2.3.1"] == [
        ("", "<b>bo", "'=cmd|' -C calc'!A0", similarity.NOT_EVIDENCE, "1.2.1")]
    assert text.count("&lt;b&gt;bo &amp; =cmd") == 3 and "nothing but the stub and the handout's equations" in text


def test_the_command_compares_a_class_offline_without_grading_it(layout, tmp_path):
    """``python -m hwtools.grade CLASS --similarity OUT``, with every socket refused: the report is
    written, nothing is graded, nothing tries the network."""
    folder = small_class(layout, tmp_path / "class")
    code = ("import socket, sys\n"
            "def refuse(*args, **kwargs):\n    raise SystemExit('a socket was opened')\n"
            "socket.socket.connect = socket.socket.connect_ex = socket.create_connection = refuse\n"
            "socket.socket.__init__ = refuse\n"
            "from hwtools.grade.__main__ import main\n"
            f"sys.exit(main([{str(folder)!r}, '--similarity', {str(tmp_path / 'out')!r}]))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=KIT, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "similarity: 4 submission(s) compared, 1 pair-TODO(s) flagged" in run.stdout
    assert "1 not read" in run.stdout and not (tmp_path / "out" / "grades.csv").exists()
    assert {path.name for path in (tmp_path / "out").iterdir()} == {"similarity.csv", "similarity.html"}
    run = subprocess.run([sys.executable, "-m", "hwtools.grade", str(folder / "ana"), "--similarity", str(tmp_path / "x")],
                         capture_output=True, text=True, cwd=KIT, timeout=60)
    assert run.returncode == 2 and "--similarity are for a folder of submissions" in run.stderr


def test_copydetect_stays_with_the_instructor():
    """The report and its package are the instructor's: the student edition leaves out the module
    (``INSTRUCTOR_ONLY``) and the requirement (``transform_requirements``), which the kit does list."""
    from instructor.given_files import transform_requirements  # noqa: PLC0415
    from instructor.kit import is_instructor_only  # noqa: PLC0415

    text = (KIT / "requirements.txt").read_text(encoding="utf-8")
    assert any(line.startswith("copydetect") for line in text.splitlines())
    assert "copydetect" not in transform_requirements(text, "requirements.txt")
    assert is_instructor_only("hwtools/grade/instructor/similarity.py")
