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
* ``total``: ``auto_earned``, ``auto_possible`` (39), ``manual_possible`` (21);
* ``todos``: one entry per TODO with ``id``, ``title``, ``auto_earned``, ``auto_possible``,
  ``manual_possible``, ``manual`` (what a person grades), ``status`` (graded, not graded, time
  limit, crashed, graded by hand), ``checks`` (what was checked, in words, its points, passed,
  ``failed_on`` visible/hidden), ``first_failure`` (for a visible input: the input, expected and
  actual value; for a hidden one only the check), ``notes`` (what was seen: stopped runs,
  warnings, code outside the blocks, suspicious calls); ``grader_error`` only where the grader
  itself failed on that TODO (it is then not graded, and a class's status says so);
* ``notes``, ``seconds``.

Modules: ``blocks`` (finding the TODO code, the kits), ``sandbox`` (launching a worker, its limits;
``bwrap_sandbox``: bubblewrap; ``user_sandbox`` and ``confine``: the fallback without namespaces, a
user of its own per run), ``worker`` (the entry point of every sandboxed process) and ``runtime``
(its loop, as a student's worker or as the reference server), ``probes`` (what a check calls in the
kit), ``served`` (which other TODOs' functions a run may call; ``served_env``: ``gym.make``'s
CartPole, answered by the grader), ``channel`` (the message format, read strictly), ``broker`` (the
grader's side of one run: numbering, schemas; ``episodes``: its records of every episode),
``reference`` (the reference servers), ``checks`` (what is checked: the table and the cases;
``cartpole_checks`` and ``logreg_checks``: each problem's inputs and judges; ``verdicts``: how an
answer is judged and shown), ``judging`` (points and feedback), ``mistakes`` (the known mistake a
failing answer matches), ``blame`` (the TODO at fault, in the preview), ``suspects`` (what a block
reaches for, named in the feedback), ``grader`` (the trusted side), ``answer_key`` (the student
edition's key), ``feedback`` (the text report); ``hwtools.cases`` rebuilds a visible input in a
student's kernel. A class: ``submissions`` (reading a submission without trusting
it), ``classroom`` (running a class), ``gradebook``, ``class_feedback`` (Markdown), ``progress``,
``safe_text``; Gradescope: ``gradescope``. This package's trusted side imports nothing from
``hwlib`` and nothing heavier than numpy.
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
