"""The student's path on macOS and on a JupyterHub (issue 39.4), where ``tests/instructor/test_student_path.py`` runs
an interrupted check and the preview on each system, and ``test_report.py`` the report and the later hand-ins on the
Windows profile: per system one run, module-scoped, with one report.

In a student edition whose every TODO is done, in a folder named as a student's may be ("Łukasz Zoë/hw1"), with a
student Python of that system (``foreign_os``; macOS: the oldest tested CPython, no ``/proc``, the refused
``RLIMIT_AS``, "spawn", "darwin" to the kit, a home of its own and no browser where a Mac keeps one; a hub: a home
read-only to all Python code, with the folders its administrator must then point elsewhere, no user namespaces,
Debian's Chromium): the student's ``handin/report/answers.tex`` is that of an earlier report (other numbers, as before
they chose their learning rate); they write words in it and hand in again, report and all (``python -m
hwtools.handin``: the visible checks, the zip, both notebooks in kernels of that Python, the PDF where there is a
browser); then they run the edition's own tests (``python -m pytest``; on the hub its unit tests: see the test).

The two systems' runs are two scheduling units of the README's test command (``conftest.py``), so that the test
processes share them.
"""

from __future__ import annotations

import subprocess

import pytest

import editions
from day_one import EDITION_TESTS_SECONDS, assert_edition_tests_pass, find_python, kit_env, student_python, versions_tested
from hwtools import handin, report
from hwtools.report import words
from hwtools.report.chromium import NO_BROWSER
from hwtools.todos import TODO_BY_ID
from reports import DERIVATION, assert_printed_as_on_linux, linux_check_texts, p1_values, p2_values

HAND_IN_SECONDS = 1800  # the visible checks and the report: about 2 min at load 2-6 (benchmarks/RESULTS.md)
MY_WORDS = "My words on {system}: Łukasz's sweep converges at every seed for the rate I chose."
EARLIER_RATE = 0.0123  # the earlier report's learning rate: not the kit's


@pytest.fixture(scope="module", params=("macos", "hub"))
def later_hand_in(request, tmp_path_factory):
    """{"system", "kit", "home", "python", "earlier": the earlier report's answers.tex as written, "said": the
    hand-in's output lines} of the later hand-in on the system."""
    system = request.param
    root = tmp_path_factory.mktemp(system)
    kit, home = root / "Łukasz Zoë" / "hw1", root / "home"
    editions.build(kit, tmp_path_factory, keep=frozenset(TODO_BY_ID))
    home.mkdir()
    python = student_python(root / "venv", system=system, home=home,
                            base=find_python(versions_tested()[0]) if system == "macos" else None)
    earlier = report.answers_latex(report.compute_answers(report.problem_one(p1_values(learning_rate=EARLIER_RATE)),
                                                          report.problem_two(p2_values(), DERIVATION)), "Ada Lovelace / alovelac")[0]
    folder = kit / "handin" / "report"
    folder.mkdir(parents=True)
    words.write_answers(folder, earlier)
    tex = folder / report.ANSWERS_TEX
    text = tex.read_text(encoding="utf-8")
    comment = next(line for line in text.splitlines() if line.startswith("% Your words: how you chose the learning rate"))
    tex.write_text(text.replace(comment, f"{comment}\n{MY_WORDS.format(system=system)}"), encoding="utf-8")
    done = subprocess.run([str(python), "-m", "hwtools.handin", "alovelac", "--name", "Ada Lovelace"],
                          capture_output=True, encoding="utf-8", errors="replace", timeout=HAND_IN_SECONDS,
                          env=kit_env(kit, python), cwd=kit)
    assert done.returncode == 0, f"the hand-in failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return {"system": system, "kit": kit, "home": home, "python": python, "earlier": earlier,
            "said": done.stdout.strip().splitlines(), "warned": done.stderr}


@pytest.mark.timeout(HAND_IN_SECONDS + 600)  # the first use of a Python of another version installs its packages
def test_a_later_hand_in_keeps_the_words_and_prints_what_linux_prints(later_hand_in, tmp_path):
    """The hand-in's visible checks pass and training converges; its zip is the one Linux writes for the same files,
    byte for byte; every cell nbval compares, the check cells and the sweep among them, prints in the report's
    kernels what it printed on Linux; the student's words are in the new answers.tex, around them the new report's
    text and none of the earlier numbers; nothing is printed on stderr (no library's warning). The Mac finds no
    Chrome where a Mac keeps one, nor Debian's Chromium: the report comes without its PDF and the hand-in says how to
    make it; the learning-rate sweep's result is kept in ~/Library/Caches/hwlib. The hub's report prints its PDF, the
    browser's profile beside the report (removed), not in the read-only home, where the sweep's result is not kept
    (and nothing is said of it). Made to fail once: with Linux's places among the Mac's browsers, the Mac's report
    printed handin/alovelac.pdf with Debian's Chromium; with ``reuse.store`` catching only PermissionError, the hub's
    sweep cell raised "OSError: [Errno 30] Read-only file system: .../home/.cache/hwlib" and the hand-in failed; with
    the hub's environment lacking MPLCONFIGDIR and IPYTHONDIR, the hub's hand-in printed matplotlib's "Matplotlib
    created a temporary cache directory ..." on stderr."""
    system, kit, home, said = (later_hand_in[key] for key in ("system", "kit", "home", "said"))
    text, out = "\n".join(said), kit / "handin"
    assert "every visible check passes" in text and "training with your LEARNING_RATE converges" in text, text
    assert not later_hand_in["warned"], later_hand_in["warned"][-3000:]  # nothing on stderr: no library's warning
    assert (out / "alovelac.zip").read_bytes() == handin.zip_bytes(kit, handin.code_files(kit))
    assert_printed_as_on_linux(out / "report", linux_check_texts(kit, tmp_path))
    assert "your words are kept in the new answers.tex" in text, text
    answers = (out / "report" / report.ANSWERS_TEX).read_text(encoding="utf-8")
    written = (out / "report" / words.AS_WRITTEN).read_text(encoding="utf-8")
    assert [line for line in answers.splitlines() if line != MY_WORDS.format(system=system)][1:] == written.splitlines()
    gone = set(later_hand_in["earlier"].splitlines()) - set(written.splitlines())  # the earlier numbers
    assert MY_WORDS.format(system=system) in answers and gone and not gone & set(answers.splitlines())
    assert f"your words in {out / 'report' / report.ANSWERS_TEX} are in no PDF yet: answers.pdf there is not made yet" in text
    assert said[-1].startswith("Hand in handin/alovelac.zip on Canvas and, once made, the report's PDF on Gradescope "
                               "(see above)."), said[-3:]
    kept = [path.parent for path in home.rglob("sweep-*.npz")]
    if system == "macos":
        assert f"{out / 'report'}: the report without its PDF (" in text and NO_BROWSER in text, text
        assert not (out / "alovelac.pdf").exists() and not (out / "report" / report.ANSWERS_PDF).exists()
        assert kept == [home / "Library" / "Caches" / "hwlib"], kept
    else:
        assert not kept, kept
        if report.chromium_path() is not None:  # this box's Debian Chromium, on the hub's PATH
            assert (out / "alovelac.pdf").read_bytes().startswith(b"%PDF"), text
            assert not list(out.rglob(".chromium-profile-*")) and not list(home.rglob("Local State"))  # no profile


@pytest.mark.timeout(EDITION_TESTS_SECONDS + 60)
def test_the_editions_own_tests_pass(later_hand_in):
    """The edition's own test command, ``python -m pytest``, on the same system after the hand-in: on the Mac the whole
    command (its unit tests, both notebooks with nbval-lax, the sweep trained again: the edition's conftest.py gives
    each test run a cache folder of its own); on the hub its unit tests, the notebooks collected. What the hub's run
    proves is its read-only home: pytest and the kit's plugins write nothing there. Its notebooks' every cell runs in
    the hub's report above (which fails on a cell's error, and where each cell nbval compares prints what it prints on
    Linux), and nbval-lax only runs them again, as it does on the Mac here and on the Windows profile
    (test_student_path.py). Made to fail once: with the kit's pytest plugin (hwtools/pytest_overrun.py) asking for
    os.sched_getaffinity and writing in ~/.cache, the Mac's run stopped at "Error while loading plugin"
    (AttributeError), the hub's too (OSError: [Errno 30])."""
    assert_edition_tests_pass(later_hand_in["python"], later_hand_in["kit"], encoding="utf-8",
                              only=("tests",) if later_hand_in["system"] == "hub" else ())
