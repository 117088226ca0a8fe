"""The grader: points per handout TODO, from code that runs sandboxed and never decides its own points.

    python -m hwtools.grade [SUBMISSION_DIR] [--reference KIT_DIR] [--json FILE] [--todo ID]

One call per submission (what batch grading builds on)::

    from hwtools.grade import grade_submission
    result = grade_submission("submissions/alice", reference_dir="path/to/instructor/kit")

or, for many submissions against one reference (its answers are computed once)::

    grader = Grader(reference_dir)
    results = [grader.grade(path) for path in paths]

The result is a JSON-serialisable dict:

* ``isolated`` (bool) and ``isolation`` (how, or why not); ``one_mistake_one_place`` (graded
  against the reference: True; against an answer key: False);
* ``total``: ``auto_earned``, ``auto_possible`` (``AUTO_POINTS``), ``manual_possible`` (``MANUAL_POINTS``);
* ``todos``: one entry per TODO with ``id``, ``title``, ``auto_earned``, ``auto_possible``,
  ``manual_possible``, ``manual`` (what a person grades), ``status`` (graded, not graded, time
  limit, crashed, graded by hand), ``checks`` (what was checked, in words, its points, passed,
  ``failed_on`` visible/hidden), ``first_failure`` (for a visible input: the input, expected and
  actual value; for a hidden one only the check), ``notes`` (what was seen: stopped runs,
  warnings, code outside the blocks, suspicious calls); ``breaks_callers`` only where an answer,
  right or not, breaks the code that calls it (1.2.1's gradient as a list: in words, also a note);
  ``grader_error`` only where the grader
  itself failed on that TODO (it is then not graded, and a class's status says so);
* ``notes``, ``seconds``; ``secret`` where there are hidden checks: the random value this grading
  drew its hidden inputs from, the instructor's to keep with the result (a regrade passes it back:
  ``grade(..., secret=...)``) and never a student's.

Where things are (``docs/design.md`` traces one grade through them):

* the trusted side, one submission: ``grader`` (``Grader``: kits, runs, judging), ``blocks``
  (finding the TODO code, reading a submission), ``kits`` (the kits the worker runs), ``broker``
  (the grader's side of one run: numbering, schemas, served calls; ``episodes``: its records of
  every CartPole episode), ``reference`` (the reference servers), ``judging`` (points and
  feedback), ``mistakes`` (the known mistake a failing answer matches), ``blame`` (the TODO at
  fault, in the preview), ``suspects`` (what a block reaches for), ``answer_key`` (the student
  edition's key), ``feedback`` (the text report and the one wording of a failure);
* what is checked: ``checks/`` (one module per problem, TODO by TODO: behaviours, points, inputs,
  probes, judges, tolerances; ``checks/verdicts``: how an answer is compared and shown);
* the launcher: ``sandbox`` (a worker's process, its limits, one run of a grading at a time) and
  ``processes`` (a worker's pipes with deadlines, the end of a process tree: on every system);
* what runs inside the sandbox: ``in_sandbox/`` (copied whole into every kit as ``_hwgrade/``:
  the worker's loop, the probes, the served-call proxies, ``gym.make``'s served CartPole, the
  message format); it imports nothing from the trusted side;
* reading a submission without trusting it: ``submissions``; ``safe_text``;
* the instructor's side, Linux's sandboxes and a class's grading: ``instructor/`` (its
  ``__init__`` lists them), never in the student edition.

``hwtools.cases`` rebuilds a visible input in a student's kernel. The trusted side imports nothing
from ``hwlib`` and nothing heavier than numpy.
"""

from hwtools.grade.grader import Grader, GradingError, write_answer_key
from hwtools.todos import AUTO_POINTS, MANUAL_POINTS, TODO_BY_ID, TODOS, Todo


def grade_submission(submission_dir, reference_dir=None, *, todos=None, grader=None, **options):
    """Grade the kit at ``submission_dir`` against ``reference_dir`` (the instructor's kit; None: the
    answer key of a student edition). ``options`` go to ``Grader`` (python, isolation,
    time_limit, memory_limit, jobs). Pass ``grader`` to reuse one (and its cached reference
    answers) across submissions. Returns the result dict described in this module's docstring."""
    grader = grader or Grader(reference_dir, **options)
    return grader.grade(submission_dir, todos=todos)


__all__ = ["AUTO_POINTS", "MANUAL_POINTS", "TODOS", "TODO_BY_ID", "Todo", "Grader", "GradingError",
           "grade_submission", "write_answer_key"]
