"""Gradescope's autograder: grade the submission in ``/autograder/submission`` and write
``/autograder/results/results.json``. The bundle's ``run_autograder`` runs

    python -m hwtools.grade.instructor.gradescope_autograder [--root /autograder]

(built by ``python -m instructor.release gradescope OUT.zip``). The root comes from ``--root``, else
the environment variable ``AUTOGRADER_ROOT``, else ``/autograder``; under it ``source/`` is the
instructor's kit (the reference and the hidden checks), ``submission/`` the student's files,
``results/results.json`` the output. ``AUTOGRADER_TIME_LIMIT`` sets the seconds per TODO's run.

The submission is read as a class's submissions are (``submissions.open_submission``: a folder or a
zip holding ``hwlib/``, at the top or a folder or two down, or the bare library files; links,
unsafe paths and oversized files refused) and graded by the sandboxed ``Grader``.

``results.json`` (Gradescope's schema) gives per TODO with automatic points two tests:

* ``<id> <title>: visible inputs``: ``visible``, 0 points; what each check gives on the inputs
  the students can see, and the first failing visible input with the expected and actual value.
  Shown at once, it says what to fix and nothing about the hidden inputs;
* ``<id> <title>``: ``after_published``, the TODO's points; every check, on visible and hidden
  inputs (hidden inputs are never shown, only that a check failed on one).

The top-level ``score`` is the automatic total; the points graded by hand are left to Gradescope's
own rubric. ``stdout`` (the full text report, for the instructor) is ``hidden``. What a student reads
before the grades are published (the top-level ``output`` with its status line and notes, the
visible tests' names and outputs) is built from the visible runs alone: a run that timed out,
failed or took longer in its hidden phase changes none of it. No run time is shown (how long the
grading took depends on the hidden runs): ``extra_data`` (instructors only) keeps the seconds.

The hidden inputs are drawn from a secret of this grading (``Grader.grade``), kept in
``extra_data["grading"]`` with the submission's id and the hash of its files. A rerun of the
autograder on the same submission reuses it where Gradescope lists that submission's earlier
results in ``submission_metadata.json`` (``stored_secret``); any other grading, a resubmission of
the same files included, draws a new one. That file is made root's alone before any student code
runs (under the user fallback a run may read every file other users may read).

Once the reference and the hidden checks are in memory, the bundle's copies of ``hwlib/`` and
``instructor/`` are deleted from ``source/`` (only where the bundle's marker file says it is the
bundle: Gradescope gives every submission a fresh container), so that no student code finds a
reference to read on disk.

Isolation: bubblewrap where it can create namespaces; where it cannot (Docker's default seccomp
profile refuses them, as Gradescope's containers very likely do), the unprivileged-user fallback
(``user_sandbox.py``: one user per run, no network sockets, a private kit folder). Before
anything runs, the autograder (as root) makes ``source/`` root's alone and takes the group and
other write bits off everything under the root that runs later; under the fallback it also kills
every process of the sandbox's users, found by uid, before it writes ``results.json`` (into
``results/``, which only root may write). The log and ``results.json``'s ``extra_data`` say which
isolation graded the submission.

Fail closed: where neither works (``setup.sh`` never ran or failed), no student code runs at all:
``results.json`` gives 0, tells the student the autograder is misconfigured, and tells the
instructor (``extra_data``, the log) why and how to fix it. A failure of the grader itself also
gives 0 and says so, rather than no ``results.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import stat
import sys
import tempfile
import time
from pathlib import Path

from hwtools.grade import kits
from hwtools.grade.instructor.class_feedback import UNGRADED_HELP, md_escape, todo_markdown
from hwtools.grade.judging import visible_view
from hwtools.grade.instructor.gradebook import GRADED, NOT_ISOLATED, status_of
from hwtools.grade.submissions import Unusable, kit_file_names, open_submission
from hwtools.grade.feedback import render
from hwtools.grade.grader import Grader, GradingError, is_secret
from hwtools.grade.sandbox import DEFAULT_TIME_LIMIT, limit_own_memory
from hwtools.todos import TODOS

BUNDLE_MARKER = "hwgrade-bundle.json"  # at the root of the bundle's source: written by instructor/gradescope_bundle.py
SCRUBBED = ("hwlib", "instructor")  # deleted from the bundle's source once loaded


def autograder_paths(root=None):
    root = Path(root or os.environ.get("AUTOGRADER_ROOT") or "/autograder")
    return {"root": root, "source": root / "source", "submission": root / "submission",
            "results": root / "results" / "results.json", "metadata": root / "submission_metadata.json"}


def _score(value):
    return float(round(value, 2))


def _tests(result):
    tests = []
    by_id = {entry["id"]: entry for entry in result["todos"]} if result else {}
    for todo in TODOS:
        if not todo.auto:
            continue
        entry = by_id.get(todo.id)
        name = f"{todo.id} {todo.title}"
        if entry is None:  # nothing was graded: the points test only, at 0
            tests.append({"name": name, "number": todo.id, "score": 0.0, "max_score": _score(todo.auto),
                          "status": "failed", "output": "Not graded: see the message at the top.",
                          "output_format": "md", "visibility": "after_published", "tags": ["points"]})
            continue
        view = visible_view(entry)  # visible verdicts and notes alone: no bit of a hidden input
        visible_pass = all(check["passed"] for check in view["checks"])
        tests.append({"name": f"{name}: visible inputs", "number": f"{todo.id}.0", "score": 0.0, "max_score": 0.0,
                      "status": "passed" if visible_pass and view["checks"] else "failed",
                      "output": todo_markdown(view, visible_only=True), "output_format": "md",
                      "visibility": "visible", "tags": ["visible inputs"]})
        earned = _score(entry["auto_earned"])
        tests.append({"name": name, "number": f"{todo.id}.1", "score": earned, "max_score": _score(todo.auto),
                      "status": "passed" if earned >= todo.auto else "failed",
                      "output": todo_markdown(entry), "output_format": "md",
                      "visibility": "after_published", "tags": ["points", "hidden inputs"]})
    return tests


MISCONFIGURED = ("The autograder is misconfigured: it has no sandbox to run your code in, so your code was not "
                 "run and earns 0 automatic points for now. This is not your fault: tell your instructor, and "
                 "submit again once it is fixed.")
FAILED = ("The autograder failed while grading your submission, so it earns 0 automatic points for now. Tell your "
          "instructor; submitting again may help.")


def results_json(result, status, notes=(), seconds=0.0, sandbox="", fault=None, grading=None):
    """Gradescope's results.json (a dict) for one submission: ``result`` is the grader's dict, or
    None when the submission could not be graded (``status`` says why: the instructor's, in
    ``extra_data``); ``sandbox``: the kind of isolation (bwrap, user or none); ``fault``: the
    autograder's own message when it could not grade (misconfigured, failed), shown instead of
    advice on the submission; ``grading``: what a regrade needs (the secret; ``extra_data``)."""
    manual = sum(todo.manual for todo in TODOS)
    # the student's status: the visible runs' alone (a hidden run's time-out is shown after publication, in
    # its TODO's test); whether the sandbox worked is the instructor's business (extra_data, stdout)
    shown = status_of(result, visible=True) if result is not None else status
    shown = "; ".join(part for part in shown.split("; ") if part != NOT_ISOLATED) or GRADED
    lines = [f"Status: **{md_escape(shown)}**", ""]
    if fault is not None:
        lines.append(fault)
    elif result is None:
        lines += ["Your submission was not graded, so it earns 0 automatic points. Fix it and submit again.", "",
                  UNGRADED_HELP]
    else:
        lines += ["Each TODO's code is checked with the reference solution for every other TODO, so a mistake costs "
                  "points only where it was made. Below, for each TODO, what your code gives on the inputs you can "
                  "see; the points, which also depend on inputs you cannot see, are shown when the grades are "
                  f"published. {manual:g} more points are graded by hand."]
        notes = list(notes) + result["notes"]
        lines += [""] * bool(notes) + [f"- note: {md_escape(note)}" for note in notes]
    data = {
        "score": _score(result["total"]["auto_earned"]) if result else 0.0,
        "output": "\n".join(lines).rstrip() + "\n",
        "output_format": "md",
        "stdout_visibility": "hidden",
        "tests": _tests(result),
        "extra_data": {"status": status, "isolated": bool(result and result["isolated"]),
                       "isolation": result["isolation"] if result else "", "sandbox": sandbox,
                       "seconds": round(seconds, 1), "grading": grading or {}},
    }
    return data


def stored_secret(metadata, files):
    """The secret of an earlier grading of this very submission (``metadata["id"]``, the same files
    ``files``) among the earlier results Gradescope lists in ``submission_metadata.json``, or None."""
    if not isinstance(metadata, dict) or metadata.get("id") is None:
        return None
    for earlier in metadata.get("previous_submissions") or []:
        results = earlier.get("results") if isinstance(earlier, dict) else None
        extra = results.get("extra_data") if isinstance(results, dict) else None
        grading = extra.get("grading") if isinstance(extra, dict) else None
        if (isinstance(grading, dict) and grading.get("submission_id") == metadata["id"]
                and grading.get("files") == files and is_secret(grading.get("secret"))):
            return grading["secret"]
    return None


def read_metadata(path):
    """``submission_metadata.json`` as a dict ({} when there is none or it cannot be read), made
    root's alone first where the autograder is root: earlier results in it hold their secrets."""
    try:
        if os.geteuid() == 0 and path.is_file() and not path.is_symlink():
            os.chown(path, 0, 0)
            path.chmod(0o600)
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _scrub(source):
    """Delete the bundle's reference and hidden checks from disk (a fresh container per submission)."""
    if not (source / BUNDLE_MARKER).is_file():
        return False
    for name in SCRUBBED:
        target = source / name
        if target.is_dir() and not target.is_symlink():
            kits.remove_tree(target)
    return True


def harden(root, source):
    """Under the user fallback: ``source/`` root's alone, and no group or other write bit on anything
    under ``root`` that runs later (the submission aside); returns the paths it changed."""
    changed = []
    if source.is_dir() and source.stat().st_mode & 0o077:
        source.chmod(0o700)
        changed.append(str(source))
    for folder, names, files in os.walk(root):
        if Path(folder) == root / "submission":
            names[:] = []
            continue
        for path in [folder, *(os.path.join(folder, name) for name in files)]:
            info = os.lstat(path)
            if not stat.S_ISLNK(info.st_mode) and info.st_mode & 0o022:
                os.chmod(path, info.st_mode & ~0o022)
                changed.append(path)
    return changed


def write_results(target, data):
    """Write ``results.json`` atomically into its folder, made root's to write."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if os.geteuid() == 0:
        os.chown(target.parent, 0, 0)
        target.parent.chmod(0o755)
    handle, temporary = tempfile.mkstemp(prefix=".results-", suffix=".json", dir=target.parent)
    with os.fdopen(handle, "w", encoding="utf-8") as stream:
        stream.write(json.dumps(data, indent=1) + "\n")
        os.fchmod(stream.fileno(), 0o644)
    os.replace(temporary, target)


def run(root=None, time_limit=None, python=None, isolation="auto", out=sys.stdout):
    """Grade ``ROOT/submission`` against ``ROOT/source``; write and return the results dict."""
    started = time.monotonic()
    paths = autograder_paths(root)
    time_limit = float(time_limit or os.environ.get("AUTOGRADER_TIME_LIMIT") or DEFAULT_TIME_LIMIT)
    metadata = read_metadata(paths["metadata"])  # before anything runs: root's alone from here on
    if os.geteuid() == 0:  # before anything runs: what runs later is root's to change, source/ root's alone
        changed = harden(paths["root"], paths["source"])
        out.write(f"source/ is root's alone; {len(changed)} path(s) under {paths['root']} made unwritable to other "
                  "users\n")
    grader = Grader(paths["source"], python=python, isolation=isolation, time_limit=time_limit)
    box = grader.sandbox
    kit_names = kit_file_names(grader.layout)
    scrubbed = _scrub(paths["source"])
    out.write(f"sandbox: {box.kind}: {box.how if box.isolated else 'NOT ISOLATED: ' + box.how}\n"
              f"grader: {Path(__file__).resolve().parents[1]}; reference: {paths['source']} (hwlib and hidden checks "
              f"{'deleted from disk once loaded' if scrubbed else 'left on disk'})\n")
    refused = grader.refusal()
    if refused:  # fail closed: no sandbox, no student code
        out.write(f"error: the autograder is misconfigured: {refused}. Check setup.sh's log (its last line says which "
                  "isolation grades): it must install bubblewrap or create the fallback's users (hwgrade1..8).\n")
        data = results_json(None, "not graded: the autograder is misconfigured (no sandbox)", (),
                            time.monotonic() - started, sandbox=box.kind, fault=MISCONFIGURED)
        data["extra_data"]["misconfigured"] = refused
        write_results(paths["results"], data)
        out.flush()
        return data
    fault, grading = None, None
    try:
        with open_submission(paths["submission"], kit_names) as opened:
            secret = stored_secret(metadata, opened.digest)  # a rerun of this submission: the same hidden inputs
            result = grader.grade(opened.kit, secret=secret)
            grading = {"secret": result.pop("secret", None), "submission_id": metadata.get("id"),
                       "files": opened.digest, "reused": secret is not None}
            result["submission"], result["reference"] = "your submission", "the reference solution"
            status, notes = status_of(result), opened.notes
    except Unusable as unusable:
        result, status, notes = None, unusable.text, []
    except Exception as error:  # noqa: BLE001 - the autograder's own failure: 0, said so, never no results.json
        result, status, notes, fault = None, f"not graded: the autograder failed ({type(error).__name__})", [], FAILED
        out.write(f"error: the grader failed: {type(error).__name__}: {error}\n")
    if box.kind == "user":
        from hwtools.grade.instructor.user_sandbox import kill_all_users  # noqa: PLC0415

        if not kill_all_users():
            raise GradingError("a process of the sandbox's users could not be killed: no results written")
        out.write("user sandbox: every process of the sandbox's users killed before results.json was written\n")
    data = results_json(result, status, notes, time.monotonic() - started, sandbox=box.kind, fault=fault,
                        grading=grading)
    write_results(paths["results"], data)
    out.write(f"status: {status}; score {data['score']:g}\n")
    if result is not None:
        out.write(render(result))
    out.flush()
    return data


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m hwtools.grade.instructor.gradescope_autograder",
                                     description="Gradescope's run_autograder: grade ROOT/submission, write "
                                                 "ROOT/results/results.json.")
    parser.add_argument("--root", help="the autograder folder (default: $AUTOGRADER_ROOT, else /autograder)")
    parser.add_argument("--time-limit", type=float, metavar="SECONDS",
                        help=f"per TODO's run (default: $AUTOGRADER_TIME_LIMIT, else {DEFAULT_TIME_LIMIT:g})")
    args = parser.parse_args(argv)
    limit = limit_own_memory()
    print(f"grader memory limit: {limit // 2**20} MiB")
    try:
        run(args.root, args.time_limit)
    except GradingError as error:
        print(f"error: the autograder cannot grade: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
