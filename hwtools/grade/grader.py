"""Grade one submission: a kit per TODO with no reference code in it, runs in the sandbox, points from the judges.

This is the trusted side. It imports the standard library, numpy and the grader's own modules;
never ``hwlib``, never anything from the submission. For each TODO T it builds a kit holding the
student's blocks for T and a stub in every other block, and runs T's cases on it in a sandboxed
worker (``broker.run_cases``): first the visible cases of every TODO, then, each in a run of its own,
the hidden ones, drawn from the grading's secret (``case_set``): 128 random bits drawn afresh for
each grading and returned with the instructor's result (``result["secret"]``), so that a regrade
that passes it back (``grade(..., secret=...)``) draws the same inputs, and nothing learnt from any
earlier grading tells anything about a later one's. When the student's code calls another TODO's function (or
``run_policy``), the worker forwards the call and the reference server answers it
(``reference.py``, ``in_sandbox/served.py``): a mistake costs points only in the TODO where it was made,
and no process that runs a student's code holds any reference solution. The reference's own
answers (``_reference_values``) and the re-scoring services come from the same server.

Where there is no reference (the student edition's preview), visible checks are judged against
the answer key the release tool writes (``write_answer_key``), the student's own kit plays the
server (every other TODO's function is the student's own), and there are no hidden checks: the
same runs, so the preview gives the instructor's verdict wherever the other TODOs are right.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.util
import os
import re
import secrets
import sys
import tempfile
import threading
import time
import weakref
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from hwtools.grade import answer_key as keys
from hwtools.grade import blame, blocks, broker, checks, judging, kits, mistakes
from hwtools.grade.answer_key import ANSWER_KEY
from hwtools.grade.in_sandbox.channel import fingerprint
from hwtools.grade.reference import ReferencePool, ServerFailed
from hwtools.grade.sandbox import DEFAULT_MEMORY_LIMIT, DEFAULT_TIME_LIMIT, Budget, Sandbox
from hwtools.todos import TODO_BY_ID, TODOS

try:  # the instructor's kit: bubblewrap's zygotes (the student edition has no sandbox, hwtools/grade/instructor/)
    from hwtools.grade.instructor.zygote import Zygotes
except ImportError:
    Zygotes = None

KIT_ROOT = Path(__file__).resolve().parents[2]
HIDDEN_CHECKS = Path("instructor") / "hidden_checks" / "__init__.py"
SERVICE_TIME_LIMIT = 900.0  # the reference's own runs (re-scoring, the notebook's training run)
BUDGET_FACTOR = 4.0  # a submission's runs take at most this many time limits of wall clock together
NOT_SERVED = ("1.3.3",)  # blocks the reference server keeps as stubs: the learning rate is 1.3.3's answer
SECRET_BYTES = 16  # a grading's secret: this many random bytes, as hex
__all__ = ["ANSWER_KEY", "KIT_ROOT", "HIDDEN_CHECKS", "Grader", "GradingError", "has_solutions", "is_secret",
           "read_answer_key", "write_answer_key"]


class GradingError(Exception):
    """The grader itself cannot run: no reference, a broken reference kit, a stale answer key."""


def default_python(reference_dir=None):
    """The kit's own Python: REFERENCE/.venv/bin/python if there is one, else this interpreter."""
    if reference_dir is not None:
        candidate = Path(reference_dir) / ".venv" / "bin" / "python"
        if candidate.exists():
            return str(candidate)
    return sys.executable


def has_solutions(kit_dir):
    try:
        layout = blocks.load_layout(kit_dir)
    except blocks.SubmissionError:
        return False
    styles = {block.style for file_blocks in layout.blocks_by_file.values() for block in file_blocks}
    return styles == {"SOLUTION"} and set(checks.GRADED_TODOS) <= set(layout.todos)


def load_hidden_checks(reference_dir):
    path = Path(reference_dir) / HIDDEN_CHECKS
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location(f"_hidden_checks_{abs(hash(str(path)))}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def read_answer_key(path):
    try:
        return keys.read(path)
    except keys.AnswerKeyError as error:
        raise GradingError(str(error)) from None


def _digest(*parts):
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part if isinstance(part, bytes) else str(part).encode())
        digest.update(b"\0")
    return digest.hexdigest()


def is_secret(value):
    """Whether ``value`` has the form of a grading's secret (``SECRET_BYTES`` bytes as lowercase hex)."""
    return isinstance(value, str) and re.fullmatch(f"[0-9a-f]{{{2 * SECRET_BYTES}}}", value) is not None


def _phase(cases):
    return [(case_id, behaviour.probe, args) for case_id, behaviour, args in cases]


class Grader:
    """Grades submissions against one reference; keeps the reference's answers between submissions.

    ``reference``: the instructor's kit (a folder whose ``hwlib`` has the solution blocks, style SOLUTION),
    or None for the answer key of a student edition (``answer_key``, default next to this module).
    ``isolation``: "auto", "bwrap", "user" or "none" (see ``Sandbox``); with a reference, "auto"
    never falls back to no sandbox (``grade`` refuses a submission other than the reference kit
    itself); only an explicit "none" runs students' code unsandboxed. ``time_limit``: CPU
    seconds per worker run of a TODO (the wall clock stops it at 3x + 10 s); ``memory_limit``:
    bytes of address space; ``budget``: wall-clock seconds all runs of one submission may take
    together (default ``BUDGET_FACTOR`` x ``time_limit``), after which its remaining TODOs are not
    run and fail as timed out. ``jobs``: threads per submission: one run executes while the
    others prepare their sandboxes (one run of a submission at a time, ``sandbox.py``), and
    judging runs alongside. Thread-safe: several submissions may be graded at once with one
    Grader, their runs side by side. ``close()`` (or ``with Grader(...) as grader``) ends its reference servers; idle ones
    end by themselves after a few seconds.
    """

    def __init__(self, reference=None, answer_key=None, python=None, isolation="auto",
                 time_limit=DEFAULT_TIME_LIMIT, memory_limit=DEFAULT_MEMORY_LIMIT, jobs=None,
                 service_time_limit=SERVICE_TIME_LIMIT, budget=None):
        self.reference = Path(reference).resolve() if reference is not None else None
        if self.reference is not None:
            if not has_solutions(self.reference):
                raise GradingError(f"{self.reference}: not an instructor's kit (its hwlib/ must hold a "
                                   f"solution block (markers of style SOLUTION) for each of {', '.join(checks.GRADED_TODOS)})")
            self.layout = blocks.load_layout(self.reference)
            self.reference_bodies = self.layout.reference_bodies()
            self.hidden = load_hidden_checks(self.reference)
            self.wrong_solutions = mistakes.read_wrong_solutions(self.reference / mistakes.WRONG_SOLUTIONS)  # read now:
            self.key = None  # the Gradescope bundle deletes instructor/ once the grader is made
        else:
            path = Path(answer_key) if answer_key is not None else ANSWER_KEY
            if not path.is_file():
                raise GradingError(f"no reference to grade against: pass --reference KIT_DIR (the instructor's kit), "
                                   f"or put the answer key at {path}")
            self.key = read_answer_key(path)
            self.layout = self.reference_bodies = self.hidden = None
            self.wrong_solutions = []
        self.cases = {todo: checks.case_set(todo, self.hidden) for todo in checks.GRADED_TODOS}
        problems = checks.points_table_problems(self.cases)
        if problems:
            raise GradingError("the points table disagrees with itself:\n  " + "\n  ".join(problems))
        if self.key is not None:
            try:
                keys.check_matches(self.key, self.cases)
            except keys.AnswerKeyError as error:
                raise GradingError(str(error)) from None
        self.sandbox = Sandbox(python or default_python(self.reference), isolation, time_limit, memory_limit)
        self.zygotes = Zygotes(self.sandbox) if self.sandbox.kind == "bwrap" else None  # between gradings
        if self.zygotes is not None:  # idle ones end with the grader, at exit at the latest (their groups removed)
            weakref.finalize(self, Zygotes.close, self.zygotes)
        self.isolation = isolation
        self._exposed = None  # under the user fallback: the reference's files a pool user can read (checked once)
        self.budget = float(budget) if budget is not None else BUDGET_FACTOR * self.sandbox.time_limit
        self.jobs = max(1, int(jobs or min(2, os.cpu_count() or 1)))  # one run executes, one is prepared
        self.service_time_limit = float(service_time_limit)
        self._memo, self._memo_lock = {}, threading.Lock()
        self._scrub = judging.Scrubber(self.reference_bodies)
        self.pool = None
        if self.reference is not None:
            server = {todo: bodies for todo, bodies in self.reference_bodies.items() if todo not in NOT_SERVED}
            self.pool = ReferencePool(self.sandbox, kits.composite_files(self.layout, server, set()))
            self._finalizer = weakref.finalize(self, ReferencePool.close, self.pool)

    def _exposure(self):
        """Under the user fallback students' code runs as the pool's users and sees every file they may
        read: the reference's files (its solutions, the hidden checks) one of them can open, tried as
        each of them (once per grader); empty otherwise."""
        if self._exposed is None:
            self._exposed = []
            if self.reference is not None and self.sandbox.kind == "user":
                from hwtools.grade.instructor.user_sandbox import readable_by_pool  # noqa: PLC0415 - the fallback only

                secret = [self.reference / relative for relative in self.layout.blocks_by_file]
                secret += [self.reference / HIDDEN_CHECKS] if (self.reference / HIDDEN_CHECKS).is_file() else []
                self._exposed = readable_by_pool(secret)
        return self._exposed

    def close(self):
        """End the reference servers and idle zygotes (a later ``grade`` starts new ones)."""
        if self.zygotes is not None:
            self.zygotes.close()
        if self.pool is not None:
            self.pool.close()
            self.pool = ReferencePool(self.pool.sandbox, self.pool.files)
            self._finalizer.detach()
            self._finalizer = weakref.finalize(self, ReferencePool.close, self.pool)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---- one submission ------------------------------------------------------------------

    def grade(self, submission, todos=None, secret=None):
        """Grade the kit at ``submission``; ``todos``: the TODO ids to grade (default: all).
        Returns a JSON-serialisable dict (see ``hwtools.grade`` for its fields). With hidden checks,
        the hidden inputs are drawn from ``secret``: a new one for a new grading (None), the one a
        grading returned (``result["secret"]``, the instructor's to keep and never a student's) for
        a regrade of the same submission, which then gets the same inputs and the same grade."""
        started = time.monotonic()
        if secret is not None and (self.hidden is None or not is_secret(secret)):
            raise ValueError(f"secret: expected None or the {2 * SECRET_BYTES} hex digits of an earlier grading's "
                             f"result['secret'] (a grading with hidden checks), got {secret!r}")
        if self.hidden is not None:
            secret = secret or secrets.token_hex(SECRET_BYTES)
        submission = Path(submission).resolve()
        refused = self.refusal(submission)
        if refused:
            raise GradingError(refused)
        selected = [todo.id for todo in TODOS if todos is None or todo.id in todos]
        unknown = sorted(set(todos or ()) - set(TODO_BY_ID))
        if unknown:
            raise GradingError(f"unknown TODO id(s): {', '.join(unknown)}")
        result = {
            "submission": str(submission),
            "reference": str(self.reference) if self.reference else "answer key (visible checks only)",
            "isolated": self.sandbox.isolated, "isolation": self.sandbox.how,
            "one_mistake_one_place": self.reference is not None,
            "notes": [], "todos": [],
        }
        if secret is not None:  # the instructor's: stored with the result, never shown to a student
            result["secret"] = secret
        layout = self.layout
        if layout is None:
            try:
                layout = blocks.load_layout(submission)
            except blocks.SubmissionError as error:
                layout = None
                result["notes"].append(f"the submission cannot be read: {error}")
        try:
            if layout is None:
                raise blocks.SubmissionError("no hwlib/ folder")
            read = blocks.read_submission(submission, layout)
        except Exception as error:  # noqa: BLE001 - one submission's failure is its own verdict
            why = str(error) if isinstance(error, blocks.SubmissionError) else _failure("read", error)
            read = blocks.Submission(submission, problems={todo: why for todo in TODO_BY_ID})
        if self.reference is not None:  # without a reference the submission's own files are what runs
            result["notes"].extend(read.notes)
        # A preview (no hidden input) runs the student's own code in servers beside its runs: it needs no turn.
        pool = self.pool if self.reference is not None else self._preview_pool(read, layout)
        graded = [todo for todo in selected if todo in checks.GRADED_TODOS]
        budget = self._grading(self.budget, layout)  # this grading's wall clock, the turn its runs take, its zygote
        built = {}  # each TODO's kit, built once per grading (``_kit_files``)

        def kit(todo):
            if todo not in built:
                built[todo] = self._kit_files(todo, read, layout)
            return built[todo]

        try:
            with ThreadPoolExecutor(max_workers=self.jobs) as executor:
                if self.hidden is not None:  # every TODO's visible run before any hidden run (``_run_and_judge``)
                    list(executor.map(lambda todo: self._visible_run(todo, kit(todo), pool, budget), graded))
                entries = dict(zip(graded, executor.map(
                    lambda todo: self._todo_entry(todo, read, layout, pool, budget, secret, kit(todo)), graded)))
            for todo in selected:
                result["todos"].append(entries.get(todo) or judging.judge_todo(todo, None, {}, None, self._expected,
                                                                               self._scrub, self._limits, []))
            self._blame(result["todos"], read, layout, pool, budget)
        finally:
            budget.close()
            if pool is not None and pool is not self.pool:
                pool.close()
        entries = result["todos"]
        result["total"] = {
            "auto_earned": round(sum(entry["auto_earned"] for entry in entries), 2),
            "auto_possible": sum(entry["auto_possible"] for entry in entries),
            "manual_possible": sum(entry["manual_possible"] for entry in entries),
        }
        result["seconds"] = round(time.monotonic() - started, 2)
        return result

    def refusal(self, submission=None):
        """Why no code of ``submission`` (None: any submission) may run here, or None. Fail closed:
        with a reference (points decided), only the reference kit itself (the instructor's own code)
        runs where "auto" found no sandbox (any other submission needs one, or an explicit
        isolation="none"), or where the user fallback's users could read the reference. The student
        edition's preview (no reference: the student's own code, no hidden input) runs without a
        sandbox, and its report says so on its first line."""
        if self.reference is None or (submission is not None and Path(submission).resolve() == self.reference):
            return None
        if not self.sandbox.isolated and self.isolation != "none":
            return (f"no sandbox works here, so no student code is run ({self.sandbox.how}). Fix the machine: install "
                    "bubblewrap and the sandbox's seccomp filter (apt-get install bubblewrap python3-seccomp), or, where "
                    "it cannot create namespaces, as root create the fallback's users (python -m "
                    "hwtools.grade.instructor.user_sandbox create) and give a Python they can run (python -m "
                    "hwtools.grade.instructor.user_sandbox python FOLDER, then --python FOLDER/bin/python); or pass "
                    "--isolation none to accept running untrusted code as yourself")
        exposed = self._exposure()
        if exposed:
            return (f"the sandbox's users can read the reference solution ({exposed[0]}, and {len(exposed) - 1} more "
                    f"file(s)): under the user fallback students' code runs as those users, so it could read it too. "
                    f"Fix: chmod o-rwx {self.reference} (or keep the kit in a folder only root may enter, such as one "
                    "made by mktemp -d), then grade again")
        return None

    # ---- running ------------------------------------------------------------------------

    @property
    def _limits(self):
        return self.sandbox.time_limit, self.sandbox.memory_limit / 2**20

    def _blame(self, entries, read, layout, pool, budget):
        """In the preview, name the TODO at fault for a failing check (``blame.py``): the TODOs it
        calls are judged on their visible checks too (run here if they were not selected)."""
        preview = self.reference is None
        judged = {entry["id"]: entry for entry in entries}
        extra = [todo for todo in checks.GRADED_TODOS if preview and todo in blame.needed(entries) and todo not in judged]
        judged.update({todo: self._todo_entry(todo, read, layout, pool, budget) for todo in extra})
        stubs = {todo for todo, bodies in read.bodies.items() if all(blame.untouched(body) for body in bodies)}
        blame.apply(entries, judged, stubs, preview)

    def _parsed_bodies(self, todo, read, layout):
        """The student's blocks for ``todo``, or a string saying why they cannot be used (a block that
        does not parse, or that the compiler cannot take: nested too deeply, too large)."""
        if todo in read.problems:
            return read.problems[todo]
        if todo not in read.bodies:  # the kit it was read with has no block of this TODO
            return (f"no code for TODO {todo} was found: its markers '### BEGIN TODO {todo}' ... "
                    f"'### END TODO {todo}' are not in your hwlib/")
        try:
            problem = kits.placement_problem(layout, todo, read.bodies[todo], read.places.get(todo))
        except (RecursionError, MemoryError, ValueError, OverflowError) as error:
            return _failure("compile", error, todo)
        if problem:
            return f"your code for TODO {todo} does not parse: {problem}"
        return read.bodies[todo]

    def _composite(self, todo, read, layout):
        """{path: text} of the kit TODO ``todo`` is checked on, or a string saying why there is none:
        the student's blocks for ``todo``, a stub in every other block, and the grader's runtime."""
        bodies = self._parsed_bodies(todo, read, layout)
        if isinstance(bodies, str):
            return bodies
        files = kits.composite_files(layout, {todo: bodies}, set(), only=checks.SETTINGS_ONLY.get(todo))
        return files | kits.sandboxed_files()

    def _preview_pool(self, read, layout):
        """Without a reference: a server on the student's own kit (each parsed block but 1.3.3's)."""
        if layout is None:
            return None
        own = {}
        for todo in read.bodies:
            bodies = self._parsed_bodies(todo, read, layout)
            if todo not in NOT_SERVED and not isinstance(bodies, str):
                own[todo] = bodies
        return ReferencePool(self.sandbox, kits.composite_files(layout, own, set()), idle=1.0, trusted=False)

    def _kit_files(self, todo, read, layout):
        """``todo``'s kit (``_composite``), or why there is none, or the error building it raised."""
        try:
            return self._composite(todo, read, layout) if layout is not None else read.problems.get(todo, "no kit")
        except Exception as error:  # noqa: BLE001 - _todo_entry gives the verdict
            return error

    def _todo_entry(self, todo, read, layout, pool, budget, secret=None, files=None):
        """The judged result entry of ``todo``: its run (without hidden inputs memoized per grader as
        the entry it gave, so that a kit already run is not run again and no run's answers are kept
        once judged; hidden inputs are the grading's own, ``secret``'s), the reference's values, the
        services its judges need. Any failure becomes the entry's verdict. ``files``: its
        ``_kit_files``, where they were built already."""
        try:
            notes = judging.seen(todo, read, layout)
        except Exception:  # noqa: BLE001 - what the code reaches for is a note; a block too deep to parse has none
            notes = []
        try:
            files = self._kit_files(todo, read, layout) if files is None else files
            if isinstance(files, Exception):
                raise files
            if isinstance(files, str):
                return self._judge(todo, {"student": files, "reference": self._reference_of(todo)}, pool, notes)
            cases = self.case_set(todo, secret)
            if cases.draw:  # this grading's own hidden inputs: no other grading draws them again
                entry = self._run_and_judge(todo, files, pool, budget, notes, cases)
                entry.pop("_budget", None)
                return entry
            key = _digest(kits.files_digest(files), pool.digest if pool else "", todo,
                          *[fingerprint({"id": case_id, "args": args}) for case_id, _, args in cases.visible + cases.hidden],
                          len(cases.visible), self.sandbox.time_limit)
            return copy.deepcopy(self._memoized(key, lambda: self._run_and_judge(todo, files, pool, budget, notes, cases),
                                                keep=lambda entry: not entry.pop("_budget", False)))
        except GradingError:
            raise
        except Exception as error:  # noqa: BLE001 - one TODO's failure is its own verdict, the others are graded
            entry = judging.judge_todo(todo, {"student": _failure("grade", error), "reference": None}, {},
                                       self.cases[todo], self._expected, self._scrub, self._limits, notes)
            entry["grader_error"] = f"{type(error).__name__}: {error}"[:300]
            return entry

    def case_set(self, todo, secret):
        """The cases ``todo`` is graded on in the grading of secret ``secret``: the visible ones, and
        hidden ones drawn from HMAC-SHA256(the hidden checks' seed, the check's id + ``secret``)
        (``hidden_cases(behaviour, draw)``). A fresh secret per grading: the inputs of any number
        of earlier gradings, of the same code or another, tell nothing of a later one's, so no
        relay between gradings can carry anything of use; the same secret (a regrade) draws the
        same inputs. Without hidden checks (or a secret): the grader's fixed cases."""
        if self.hidden is None or not secret:
            return self.cases[todo]
        return checks.case_set(todo, self.hidden, secret)

    def case_sets(self, secret):
        """{TODO: its case set} in the grading of secret ``secret`` (``result["secret"]``)."""
        return {todo: self.case_set(todo, secret) for todo in checks.GRADED_TODOS}

    def _reference_of(self, todo, cases=None):
        return self._reference_values(todo, cases) if self.reference is not None else None

    def _visible_run(self, todo, files, pool, budget):
        """The run of ``todo``'s visible cases alone in its kit ``files`` (``_kit_files``; memoized per code, as
        the known mistakes' runs; a run its submission's budget stopped is not kept), or None when its code
        cannot run."""
        if isinstance(files, (str, Exception)):
            return None
        return self._memoized(("visible", kits.files_digest(files), pool.digest if pool else "", todo),
                              lambda: self._run_now(todo, files, _phase(self.cases[todo].visible), [], pool, budget),
                              keep=lambda run: not run[0].budget)

    def _run_and_judge(self, todo, files, pool, budget, notes, cases):
        """Run and judge ``todo``. With hidden cases, two runs: the visible one (every TODO's ran before
        this, ``grade``), then, only if that one ended well and answered something, the hidden one, so
        that no run that can still send text back to a student begins after a run that saw a hidden
        input. A hidden run that stops is a stop in the hidden phase (nothing of it is shown)."""
        if not cases.hidden:  # its visible run is all (run already in the visible phase where there are hidden checks)
            student = self._visible_run(todo, files, pool, budget)
        else:
            outcome, results = self._visible_run(todo, files, pool, budget)
            student = (outcome, dict(results))
            if outcome.status == "ok" and any(result.get("status") == "ok" for result in results.values()):
                hidden_outcome, hidden_results = self._run_now(todo, files, [], _phase(cases.hidden), pool, budget)
                hidden_outcome.notes = list(dict.fromkeys(outcome.notes + hidden_outcome.notes))
                hidden_outcome.visible_notes = outcome.visible_notes  # the hidden run's own: none
                hidden_outcome.seconds += outcome.seconds
                student = (hidden_outcome, {**results, **hidden_results})
        run = {"student": student, "reference": self._reference_of(todo, cases)}
        entry = self._judge(todo, run, pool, notes, cases)
        entry["_budget"] = run["student"][0].budget  # another submission with this code gets its own budget
        return entry

    def _judge(self, todo, run, pool, notes, cases=None):
        cases = cases or self.cases[todo]
        services = self._services(self._service_requests(todo, run, cases), pool)
        return judging.judge_todo(todo, run, services, cases, self._expected, self._scrub, self._limits, notes,
                                  self.known_mistakes)

    def _grading(self, seconds, layout):
        """The ``Budget`` of a grading of ``seconds``: under bubblewrap with a zygote that forks its runs of
        student code (``instructor/zygote.py``), which compiles the modules of ``layout`` that ``import
        hwlib`` reaches, every TODO a stub: a new one, or one an earlier grading left idle on that kit."""
        if self.zygotes is None:
            return Budget(seconds)
        template = None if layout is None else kits.composite_files(layout, {}, set(), only=("hwlib/__init__.py",))
        return Budget(seconds, self.zygotes.take(template))

    def _run_now(self, todo, files, visible, hidden, pool, budget=None):
        """One run of ``todo``'s kit ``files`` on those cases, in its grading's turn (``budget``)."""
        return broker.run_cases(self.sandbox.start(files, budget=budget), todo, visible, hidden, pool)

    def _reference_values(self, todo, cases=None):
        """{case id: the reference's values} for every exact case of ``todo`` (its case set ``cases``,
        default the grader's own, memoized per grader; one grading's own are used once)."""
        cases = cases or self.cases[todo]

        def compute():
            values = {}
            for case_id, behaviour, args in cases.visible + cases.hidden:
                if not behaviour.exact:
                    continue
                try:
                    result = self.pool.probe(behaviour.probe, args, self.service_time_limit)
                except ServerFailed as error:
                    raise GradingError(f"the reference server failed on TODO {todo}'s check {case_id}: {error}") from None
                if result["status"] != "ok":
                    raise GradingError(f"the reference solution of TODO {todo} fails its own check {case_id}: "
                                       f"{result['error']}")
                values[case_id] = result["values"]
            return values

        return compute() if cases.draw else self._memoized(("reference", todo), compute)

    def _memoized(self, key, compute, keep=lambda value: True):
        """``compute()``, once per ``key`` for this grader (threads asking at once wait for the first);
        a value that ``keep`` refuses is returned but not kept."""
        with self._memo_lock:
            entry = self._memo.get(key)
            owner = entry is None
            if owner:
                entry = self._memo[key] = {"event": threading.Event(), "value": None}
        if owner:
            try:
                entry["value"] = compute()
                if not keep(entry["value"]):
                    with self._memo_lock:
                        self._memo.pop(key, None)
            except BaseException as error:  # noqa: BLE001 - handed to every waiter
                entry["error"] = error
                with self._memo_lock:
                    self._memo.pop(key, None)
            finally:
                entry["event"].set()
        entry["event"].wait()
        if "error" in entry:
            raise entry["error"]
        return entry["value"]

    # ---- known mistakes: what each wrong solution gives on the visible inputs (mistakes.py) ----

    def known_mistakes(self, todo):
        """The known mistakes' table (``mistakes.py``): from the answer key, or, with a reference,
        each of its wrong solutions of ``todo`` run on the visible inputs like a student's code
        (memoized per grader: a class pays for it once)."""
        if self.key is not None:
            return self.key.get("mistakes", [])
        if self.reference is None:
            return []
        return self._memoized(("mistakes", todo), lambda: self._mistake_table(todo))

    def _mistake_table(self, todo):
        wrong = [w for w in self.wrong_solutions if w.todo == todo]
        visible = checks.CaseSet(todo, visible=self.cases[todo].visible)

        def signature(solution):
            with tempfile.TemporaryDirectory(prefix="hwgrade-mistake-", ignore_cleanup_errors=True) as scratch:
                kits.write_submission(self.layout, scratch, {todo: list(solution.bodies)}, others="stub")
                read = blocks.read_submission(Path(scratch), self.layout)
            files = self._composite(todo, read, self.layout)
            if isinstance(files, str):
                return None
            student = self._memoized(("visible", kits.files_digest(files), self.pool.digest, todo),
                                     lambda: self._run_now(todo, files, _phase(visible.visible), [], self.pool, forked))
            run = {"student": student, "reference": self._reference_values(todo)}
            services = self._services(self._service_requests(todo, run, visible), self.pool)
            entry = judging.judge_todo(todo, run, services, visible, self._expected, self._scrub, self._limits, [])
            return mistakes.table_entry(solution, mistakes.signature(visible.visible, student[1], entry))

        # under bubblewrap the table's runs are forked by a zygote of their own, in turns, each bounded by its own limits
        table = self._grading(float("inf"), self.layout)
        forked = table if table.zygote is not None else None  # elsewhere side by side, as before
        try:
            with ThreadPoolExecutor(max_workers=self.jobs) as executor:
                return [known for known in executor.map(signature, wrong) if known is not None]
        finally:
            table.close()

    # ---- services: the reference re-scores what a student's run produced ------------------

    def _service_requests(self, todo, run, cases=None):
        student = run["student"]
        if isinstance(student, str):
            return []
        outcome, results = student
        cases = cases or self.cases[todo]
        needed = []
        for behaviour in checks.BEHAVIOURS_BY_TODO[todo]:
            if behaviour.services is None:
                continue
            for case_id, case_behaviour, args in cases.visible + cases.hidden:
                if case_behaviour is checks.cases_of(behaviour):
                    needed.extend(behaviour.services(args, results.get(case_id) or broker.missing(outcome)))
        return needed

    def _services(self, needed, pool):
        """{service key: result} for every (probe, args) in ``needed``, each run once per Grader."""
        answers = {}
        for probe, args in needed:
            key = judging.service_key(probe, args)
            if key in answers:
                continue
            if pool is None:
                answers[key] = {"status": "error", "error": "not run", "warnings": [], "values": {}}
                continue

            try:
                answers[key] = self._memoized(("service", pool.digest, key),
                                              lambda probe=probe, args=args: pool.probe(probe, args, self.service_time_limit))
            except ServerFailed as error:
                answers[key] = {"status": "error", "error": str(error), "warnings": [], "values": {}}
        return answers

    def _expected(self, case_id, behaviour, reference):
        if not behaviour.exact:
            return None
        if self.key is not None:
            return self.key["expected"].get(case_id)
        return reference.get(case_id)


def _failure(step, error, todo=None):
    """One line saying why a submission (or its TODO ``todo``) could not be read, compiled or graded."""
    why = {RecursionError: "nested too deeply for Python's compiler", MemoryError: "too large to hold in memory"}
    kind = type(error).__name__
    detail = next((words for cls, words in why.items() if isinstance(error, cls)), str(error)[:200] or kind)
    if step == "compile":
        return f"your code for TODO {todo} cannot be compiled ({kind}: {detail})"
    if step == "read":
        return f"the submission cannot be read ({kind}: {detail})"
    return f"the grader failed on this TODO's code ({kind}: {detail}); it was not graded"


def write_answer_key(reference_kit, out_path, python=None, isolation="auto"):
    """Write the answer key of the student edition: the reference's values for the VISIBLE
    inputs of the exact checks (nothing about hidden checks), as JSON at ``out_path``."""
    with Grader(reference_kit, python=python, isolation=isolation) as grader:
        expected = {}
        for todo in checks.GRADED_TODOS:
            for case_id, behaviour, args in grader.cases[todo].visible:
                if behaviour.exact:
                    result = grader.pool.probe(behaviour.probe, args, grader.service_time_limit)
                    if result["status"] != "ok":
                        raise GradingError(f"the reference fails visible check {case_id}: {result['error']}")
                    expected[case_id] = result["values"]
        known = [entry for todo in checks.GRADED_TODOS for entry in grader.known_mistakes(todo)]
        return keys.write(expected, {todo: grader.cases[todo] for todo in checks.GRADED_TODOS}, out_path, known,
                          grader.wrong_solutions)
