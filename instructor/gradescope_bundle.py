"""Build the zip that Gradescope's "Configure Autograder" takes.

    python -m instructor.release gradescope OUT.zip [--source KIT_DIR] [--force]

At the zip's root:

* ``setup.sh``: run once by Gradescope, as root, while it builds the image (the only time the
  network is used): Python with ``venv``, bubblewrap where the image's packages have it, the
  unprivileged-user fallback (``setpriv``, Debian's ``python3-seccomp``, the users ``hwgrade1``..8),
  and a virtual environment in ``/autograder/venv`` with the packages the graded code imports
  (``requirements.txt``: the kit's own lines for them); what runs later is made root's to write,
  ``source/`` root's alone; the log's last line says which isolation will grade;
* ``run_autograder``: run for each submission; grades ``/autograder/submission`` with
  ``python -m hwtools.grade.instructor.gradescope_autograder`` and writes ``/autograder/results/results.json``. Paths
  come from ``AUTOGRADER_ROOT`` (default ``/autograder``) and ``AUTOGRADER_PYTHON`` (default the
  venv's Python), so that a test can run it in a temporary folder laid out like ``/autograder``;
* what they need: the instructor's ``hwlib/`` (the reference solution), ``hwtools/`` (the grader),
  ``instructor/hidden_checks/`` and ``instructor/wrong_solutions/`` (the known mistakes: the grader
  runs each on the visible checks, so that a student's feedback names the mistake their answers
  match, as the preview and the class run do). Not the notebooks, tests, benchmarks, data or the
  release tool. The bundle stays with the instructor and Gradescope: it holds the solutions and the
  hidden checks;
* ``hwgrade-bundle.json``: what the bundle is and holds (the grader deletes the reference from a
  container's disk only where it finds this file).

The zip depends only on the kit's files (sorted, fixed time stamps): two builds are identical.
A kit the release gate finds not ready (``instructor/gate.py``) is refused before anything is written.
"""

from __future__ import annotations

import json
import re
import sys
import zipfile
from pathlib import Path

from hwtools.grade.instructor.user_sandbox import GRADED_PACKAGES as GRADING_REQUIREMENTS  # what hwlib imports in the worker
from instructor.kit import kit_files

BUNDLED = ("hwlib/", "hwtools/", "instructor/hidden_checks/", "instructor/wrong_solutions/")  # path prefixes of the kit
LEFT_OUT = ("hwtools/grade/answer_key.json",)  # the student edition's key: the bundle grades with the reference
FIXED_TIME = (1980, 1, 1, 0, 0, 0)

SETUP_SH = """\
#!/usr/bin/env bash
# Gradescope runs this once, as root, while it builds the autograder's image: the only step with
# network access. It installs Python, bubblewrap (the sandbox for students' code) and, for
# containers where bubblewrap cannot create namespaces, the fallback's tools (setpriv, and
# python3-seccomp for the filter of every run: no socket, no file made) and its users; then a virtual
# environment with the packages the graded code imports, and says which isolation will be used.
set -euo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
SOURCE="$ROOT/source"
export DEBIAN_FRONTEND=noninteractive PIP_DISABLE_PIP_VERSION_CHECK=1
apt-get update -qq
apt-get install -y -qq --no-install-recommends python3 python3-venv python3-pip util-linux python3-seccomp >/dev/null
if ! apt-get install -y -qq --no-install-recommends bubblewrap >/dev/null; then
    echo "bubblewrap is not available: submissions will be graded by the unprivileged-user fallback"
fi
python3 -c 'import sys; assert sys.version_info >= (3, 10), "the kit needs Python 3.10 or newer"'
python3 -m venv "$ROOT/venv"
"$ROOT/venv/bin/python" -m pip install --quiet --no-cache-dir -r "$SOURCE/requirements.txt"
chmod +x "$SOURCE/run_autograder"
cd "$SOURCE"
"$ROOT/venv/bin/python" -c "import numpy, gymnasium, hwtools.grade"
# The fallback's users (one per run at a time): hwgrade1..hwgrade8, no login, no home.
"$ROOT/venv/bin/python" -m hwtools.grade.instructor.user_sandbox create
# What runs later is root's to change: the sandbox's users may run the venv, never write it.
chown -R root:root "$ROOT/venv" "$SOURCE"
chmod -R go-w "$ROOT/venv" "$SOURCE"
chmod 755 "$ROOT" "$ROOT/venv"
chmod 700 "$SOURCE"
# Says in the image build's log which isolation grades the submissions (bwrap or user); with none,
# no submission is graded (each gets 0 and "the autograder is misconfigured") until this is fixed.
"$ROOT/venv/bin/python" -c "
from hwtools.grade.sandbox import Sandbox
box = Sandbox('$ROOT/venv/bin/python')
print('isolation:', box.kind, '-', box.how if box.isolated else 'NO SANDBOX, SO NO SUBMISSION WILL BE GRADED: ' + box.how)"
"""

RUN_AUTOGRADER = """\
#!/usr/bin/env bash
# Gradescope runs this for each submission, in a fresh container: it grades
# $ROOT/submission against the reference in $ROOT/source and writes $ROOT/results/results.json.
# No network is needed. AUTOGRADER_ROOT and AUTOGRADER_PYTHON move it (tests run it in a temporary folder).
set -euo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
PYTHON="${AUTOGRADER_PYTHON:-$ROOT/venv/bin/python}"
cd "$ROOT/source"
export PYTHONPATH="$ROOT/source" PYTHONDONTWRITEBYTECODE=1 MPLBACKEND=Agg
exec "$PYTHON" -m hwtools.grade.instructor.gradescope_autograder --root "$ROOT"
"""


class BundleError(Exception):
    """The kit cannot make a bundle (no solutions, no hidden checks, a requirement missing)."""


def grading_requirements(source):
    """The kit's requirements.txt lines for the packages the graded code imports."""
    path = Path(source) / "requirements.txt"
    if not path.is_file():
        raise BundleError(f"{path}: missing; the bundle installs the kit's own requirement lines")
    lines = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^\s*([A-Za-z0-9_.-]+)", line)
        if match and not line.lstrip().startswith(("#", "-")):
            name = match[1].lower().replace("_", "-")
            if name in GRADING_REQUIREMENTS:
                lines[name] = line.split("#")[0].strip()
    missing = [name for name in GRADING_REQUIREMENTS if name not in lines]
    if missing:
        raise BundleError(f"{path}: no line for {', '.join(missing)}")
    return [lines[name] for name in GRADING_REQUIREMENTS]


def bundle_files(source):
    """{name in the zip: (bytes, executable)} of the bundle for the instructor's kit at ``source``."""
    from hwtools.grade.grader import HIDDEN_CHECKS, has_solutions  # noqa: PLC0415 - numpy only when building
    from hwtools.grade.instructor.gradescope_autograder import BUNDLE_MARKER  # noqa: PLC0415

    source = Path(source).resolve()
    if not has_solutions(source):
        raise BundleError(f"{source}: not an instructor's kit (its hwlib/ must hold every TODO's solution block)")
    if not (source / HIDDEN_CHECKS).is_file():
        raise BundleError(f"{source / HIDDEN_CHECKS}: missing; without hidden checks a hard-coded answer would pass")
    files = {}
    for name in kit_files(source):
        if name.startswith(BUNDLED) and name not in LEFT_OUT:
            path = source / name
            files[name] = (path.read_bytes(), bool(path.stat().st_mode & 0o111))
    requirements = "# The packages the graded code imports (the kit's own lines); installed by setup.sh\n"
    files["requirements.txt"] = ((requirements + "\n".join(grading_requirements(source)) + "\n").encode(), False)
    files["setup.sh"] = (SETUP_SH.encode(), True)
    files["run_autograder"] = (RUN_AUTOGRADER.encode(), True)
    marker = {"what": "Gradescope autograder bundle of the Robot Autonomy HW1 kit",
              "made_by": "python -m instructor.release gradescope",
              "files": sorted([*files, BUNDLE_MARKER])}
    files[BUNDLE_MARKER] = ((json.dumps(marker, indent=1) + "\n").encode(), False)
    return files


def build_bundle(source, out_zip, force=False):
    """Write the Gradescope bundle of the kit at ``source`` to ``out_zip``; returns the names in it."""
    out_zip = Path(out_zip)
    if out_zip.suffix.lower() != ".zip":
        raise BundleError(f"{out_zip}: the bundle is a .zip file; name it OUT.zip")
    if out_zip.exists() and not force:
        raise BundleError(f"{out_zip}: exists (pass --force to replace it)")
    files = bundle_files(source)
    out_zip.parent.mkdir(parents=True, exist_ok=True)
    temporary = out_zip.with_name(out_zip.name + ".part")
    with zipfile.ZipFile(temporary, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, (data, executable) in sorted(files.items()):
            info = zipfile.ZipInfo(name, date_time=FIXED_TIME)
            info.create_system = 3  # unix: the permission bits below count
            info.external_attr = (0o100755 if executable else 0o100644) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, data)
    temporary.replace(out_zip)
    return sorted(files)


def add_parser(commands, default_source):
    """The release tool's ``gradescope`` subcommand."""
    parser = commands.add_parser("gradescope", help="the Gradescope autograder bundle (a zip for Configure Autograder); "
                                                    "it holds the solutions and hidden checks: never give it to students")
    parser.add_argument("out_zip", metavar="OUT.zip", help="the zip to write")
    parser.add_argument("--source", default=str(default_source), help="the instructor's kit (default: this kit)")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT.zip")
    parser.set_defaults(run=main)
    return parser


def main(args):
    from instructor import gate  # noqa: PLC0415 - the facts tool, only for the command

    try:
        gate.check(args.source, "the Gradescope bundle")
        names = build_bundle(args.source, args.out_zip, force=args.force)
    except (BundleError, gate.Refused) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"Gradescope bundle: {len(names)} files in {args.out_zip} (instructor only: it holds the solutions and the "
          "hidden checks). Upload it under Configure Autograder.")
    return 0
