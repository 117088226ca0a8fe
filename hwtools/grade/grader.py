"""Grade one submission: build a kit per TODO, run the worker on it in the sandbox, judge the answers.

This is the trusted side. It imports the standard library, numpy and the grader's own modules;
never ``hwlib``, never anything from the submission. For each TODO T it builds a *composite* kit:
the reference kit's ``hwlib`` with T's blocks replaced by the student's code for T, the blocks T's
check calls (``checks.NEEDS``) kept as the reference solution, and every other block stubbed. So a
mistake costs points only in the TODO where it was made. The reference's own answers come from
the same worker on the same composite built with the reference's code for T, in the sandbox too.

Where there is no reference (the student edition), visible checks are judged against the answer
key the release tool writes (``write_answer_key``), the student's whole kit stands in for the
composite, and there are no hidden checks.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from hwtools.grade import blocks, checks
from hwtools.grade import worker as protocol
from hwtools.grade.sandbox import DEFAULT_MEMORY_LIMIT, DEFAULT_TIME_LIMIT, Sandbox
from hwtools.todos import TODO_BY_ID, TODOS

KIT_ROOT = Path(__file__).resolve().parents[2]
ANSWER_KEY = Path(__file__).resolve().with_name("answer_key.json")
HIDDEN_CHECKS = Path("instructor") / "hidden_checks" / "__init__.py"
SERVICE_TIME_LIMIT = 900.0  # the reference's own runs (re-scoring, the notebook's training run)
ANSWER_KEY_VERSION = 1


class GradingError(Exception):
    """The grader itself cannot run: no reference, a broken reference kit, a stale answer key."""


def _id_key(todo):
    return tuple(int(part) for part in todo.split("."))


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


def _digest(*parts):
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part if isinstance(part, bytes) else str(part).encode())
        digest.update(b"\0")
    return digest.hexdigest()


class Grader:
    """Grades submissions against one reference; keeps the reference's answers between submissions.

    ``reference``: the instructor's kit (a folder whose ``hwlib`` has the solution blocks, style SOLUTION),
    or None for the answer key of a student edition (``answer_key``, default next to this module).
    ``isolation``: "auto", "bwrap" or "none" (see ``Sandbox``). ``time_limit``: seconds of wall
    clock (and CPU) per worker run of a TODO; ``memory_limit``: bytes of address space.
    ``jobs``: worker runs of one submission side by side. Thread-safe: several submissions may be
    graded at once with one Grader.
    """

    def __init__(self, reference=None, answer_key=None, python=None, isolation="auto",
                 time_limit=DEFAULT_TIME_LIMIT, memory_limit=DEFAULT_MEMORY_LIMIT, jobs=None,
                 service_time_limit=SERVICE_TIME_LIMIT):
        self.reference = Path(reference).resolve() if reference is not None else None
        if self.reference is not None:
            if not has_solutions(self.reference):
                raise GradingError(f"{self.reference}: not an instructor's kit (its hwlib/ must hold a "
                                   f"solution block (markers of style SOLUTION) for each of {', '.join(checks.GRADED_TODOS)})")
            self.layout = blocks.load_layout(self.reference)
            self.reference_bodies = self.layout.reference_bodies()
            self.hidden = load_hidden_checks(self.reference)
            self.key = None
        else:
            path = Path(answer_key) if answer_key is not None else ANSWER_KEY
            if not path.is_file():
                raise GradingError(f"no reference to grade against: pass --reference KIT_DIR (the instructor's kit), "
                                   f"or put the answer key at {path}")
            self.key = read_answer_key(path)
            self.layout = self.reference_bodies = self.hidden = None
        self.cases = {todo: checks.case_set(todo, self.hidden) for todo in checks.GRADED_TODOS}
        if self.key is not None:
            _check_key_matches(self.key, self.cases)
        self.sandbox = Sandbox(python or default_python(self.reference), isolation, time_limit, memory_limit)
        self.jobs = max(1, int(jobs or min(4, os.cpu_count() or 1)))
        self.service_time_limit = float(service_time_limit)
        self._memo, self._memo_lock = {}, threading.Lock()
        self._secret_lines = self._reference_lines()

    # ---- one submission ------------------------------------------------------------------

    def grade(self, submission, todos=None):
        """Grade the kit at ``submission``; ``todos``: the TODO ids to grade (default: all).
        Returns a JSON-serialisable dict (see ``hwtools.grade`` for its fields)."""
        started = time.monotonic()
        submission = Path(submission).resolve()
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
        layout = self.layout
        if layout is None:
            try:
                layout = blocks.load_layout(submission)
            except blocks.SubmissionError as error:
                layout = None
                result["notes"].append(f"the submission cannot be read: {error}")
        if layout is not None:
            read = blocks.read_submission(submission, layout)
        else:
            read = blocks.Submission(submission, problems={todo: "no hwlib/ folder" for todo in TODO_BY_ID})
        if self.reference is not None:  # without a reference the submission's own files are what runs
            result["notes"].extend(read.notes)

        graded = [todo for todo in selected if todo in checks.GRADED_TODOS]
        with ThreadPoolExecutor(max_workers=self.jobs) as pool:
            runs = dict(zip(graded, pool.map(lambda todo: self._run_todo(todo, read, layout), graded)))
        needed = []
        for todo in graded:
            needed.extend(self._service_requests(todo, runs[todo]))
        services = self._services(needed, read, layout)
        for todo in selected:
            result["todos"].append(self._judge_todo(todo, runs.get(todo), services, read, layout))
        entries = result["todos"]
        result["total"] = {
            "auto_earned": round(sum(entry["auto_earned"] for entry in entries), 2),
            "auto_possible": sum(entry["auto_possible"] for entry in entries),
            "manual_possible": sum(entry["manual_possible"] for entry in entries),
        }
        result["seconds"] = round(time.monotonic() - started, 2)
        return result

    # ---- running ------------------------------------------------------------------------

    def _composite(self, todo, read, layout):
        """{path: text} of the kit TODO ``todo`` is checked on, or a string saying why there is none."""
        if todo in read.problems:
            return read.problems[todo]
        bodies = read.bodies[todo]
        module_level = any(block.module_level for file_blocks in layout.blocks_by_file.values()
                           for block in file_blocks if block.todo == todo)
        for body in bodies:
            problem = blocks.check_body(body, module_level)
            if problem:
                return f"your code for TODO {todo} does not parse ({problem})"
        only = checks.SETTINGS_ONLY.get(todo)
        if self.reference is None:  # no reference: the student's own kit, all their blocks
            return blocks.composite_files(layout, dict(read.bodies), (), only=only)
        return blocks.composite_files(layout, {todo: bodies}, set(checks.NEEDS[todo]), only=only)

    def _run_todo(self, todo, read, layout):
        """{"student": (outcome, results by case id) or a reason string, "reference": the same or None}."""
        cases = self.cases[todo]
        files = self._composite(todo, read, layout) if layout is not None else read.problems.get(todo, "no kit")
        student = self._run(files, cases.requests()) if isinstance(files, dict) else files
        reference = None
        if self.reference is not None and any(b.exact for b in checks.BEHAVIOURS_BY_TODO[todo]):
            reference_files = blocks.composite_files(self.layout, {todo: self.reference_bodies[todo]},
                                                     set(checks.NEEDS[todo]), only=checks.SETTINGS_ONLY.get(todo))
            reference = self._run(reference_files, cases.requests())
            if reference[0].status != "ok" or any(r["status"] != "ok" for r in reference[1].values()):
                bad = next((r for r in reference[1].values() if r["status"] != "ok"), None)
                raise GradingError(f"the reference solution of TODO {todo} fails its own checks: "
                                   f"{reference[0].status} {reference[0].detail} {bad['error'] if bad else ''}")
        return {"student": student, "reference": reference, "files": files if isinstance(files, dict) else None}

    def _run(self, files, requests, time_limit=None):
        key = _digest(blocks.files_digest(files), *[protocol.fingerprint(request) for request in requests], time_limit)
        return self._memoized(key, lambda: self._run_now(files, requests, time_limit))

    def _run_now(self, files, requests, time_limit):
        with tempfile.TemporaryDirectory(prefix="hwgrade-kit-") as scratch:
            kit = blocks.write_files(files, Path(scratch) / "kit")
            try:
                outcome = self.sandbox.run(kit, requests, time_limit)
            finally:
                for path in Path(scratch).rglob("*"):
                    path.chmod(0o700)
        results = {}
        for answer in outcome.answers:
            for item in answer["results"]:
                if isinstance(item, dict) and isinstance(item.get("id"), str):
                    results.setdefault(item["id"], _clean_result(item))
        return outcome, results

    def _memoized(self, key, compute):
        with self._memo_lock:
            entry = self._memo.get(key)
            if entry is None:
                entry = self._memo[key] = {"event": threading.Event(), "value": None}
                owner = True
            else:
                owner = False
        if owner:
            try:
                entry["value"] = compute()
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

    # ---- services: the reference re-scores what a student's run produced ------------------

    def _service_requests(self, todo, run):
        student = run["student"]
        if isinstance(student, str):
            return []
        outcome, results = student
        needed = []
        for case_id, behaviour, args in self.cases[todo].visible + self.cases[todo].hidden:
            if behaviour.services is None:
                continue
            result = results.get(case_id) or _missing(outcome)
            needed.extend(behaviour.services(args, result))
        return needed

    def _service_files(self, read, layout):
        if self.reference is not None:
            return blocks.composite_files(self.layout, dict(self.reference_bodies), set())
        return blocks.composite_files(layout, dict(read.bodies), ()) if layout is not None else None

    def _services(self, needed, read, layout):
        """{service key: result} for every (probe, args) in ``needed``, each run once per Grader."""
        answers, missing = {}, []
        for probe, args in needed:
            key = _digest(probe, protocol.fingerprint({"args": args}))
            with self._memo_lock:
                cached = self._memo.get(("service", key))
            if cached is not None:
                answers[key] = cached
            elif key not in {k for k, _, _ in missing}:
                missing.append((key, probe, args))
        if missing:
            files = self._service_files(read, layout)
            request = {"cases": [{"id": key, "probe": probe, "args": args} for key, probe, args in missing]}
            if files is None:
                outcome, results = None, {}
            else:
                outcome, results = self._run_now(files, [request], self.service_time_limit)
            for key, _, _ in missing:
                result = results.get(key) or _missing(outcome)
                answers[key] = result
                if result["status"] == "ok" and self.reference is not None:
                    with self._memo_lock:
                        self._memo[("service", key)] = result
        return answers

    # ---- judging and feedback -------------------------------------------------------------

    def _judge_todo(self, todo, run, services, read, layout):
        info = TODO_BY_ID[todo]
        entry = {"id": todo, "title": info.title, "auto_earned": 0.0, "auto_possible": info.auto,
                 "manual_possible": info.manual, "manual": info.manual_what, "code": info.code,
                 "status": "graded", "checks": [], "first_failure": None, "notes": []}
        if run is None:
            entry["status"] = "graded by hand" if info.manual else "no checks"
            return entry
        student = run["student"]
        if isinstance(student, str):
            entry["status"] = "not graded"
            entry["notes"].append(student)
            outcome, results = None, {}
        else:
            outcome, results = student
            if outcome.status != "ok":
                entry["status"] = {"timeout": "time limit", "ended": "crashed", "garbled": "crashed"}[outcome.status]
                entry["notes"].append(f"the run of your code stopped: {outcome.detail} "
                                      f"(after {outcome.seconds:.1f} s; time limit {self.sandbox.time_limit:.0f} s, "
                                      f"memory limit {self.sandbox.memory_limit // 2**20} MiB)")
        reference = run["reference"][1] if run["reference"] else {}
        earned = 0.0
        warnings = []
        for behaviour in checks.BEHAVIOURS_BY_TODO[todo]:
            verdicts = []
            for visible, phase in ((True, self.cases[todo].visible), (False, self.cases[todo].hidden)):
                for case_id, case_behaviour, args in phase:
                    if case_behaviour is not behaviour:
                        continue
                    result = results.get(case_id) or _missing(outcome, isinstance(student, str) and student)
                    if visible:
                        warnings.extend(result.get("warnings", []))
                    expected = self._expected(case_id, behaviour, reference)
                    if behaviour.exact and expected is None:
                        continue  # a hidden case with only an answer key: not checked here
                    wanted = behaviour.services(args, result) if behaviour.services else []
                    answers = [services.get(_digest(probe, protocol.fingerprint({"args": a}))) for probe, a in wanted]
                    try:
                        verdict = behaviour.judge(args, result, expected, answers)
                    except Exception as error:  # noqa: BLE001 - malformed values from the worker
                        verdict = checks.Verdict(False, "", f"unexpected values ({type(error).__name__}: {error})")
                    verdicts.append((visible, args, verdict))
            passed = bool(verdicts) and all(verdict.passed for _, _, verdict in verdicts)
            failed_on = None if passed else ("visible" if any(v and not d.passed for v, _, d in verdicts) else "hidden")
            earned += behaviour.points if passed else 0.0
            entry["checks"].append({
                "check": behaviour.description, "points": behaviour.points, "passed": passed, "failed_on": failed_on,
                "visible_inputs": sum(v for v, _, _ in verdicts), "hidden_inputs": sum(not v for v, _, _ in verdicts)})
            if entry["first_failure"] is None and not passed:
                first = next(((args, verdict) for v, args, verdict in verdicts if v and not verdict.passed), None)
                if first is not None:
                    args, verdict = first
                    entry["first_failure"] = {"check": behaviour.description, "hidden": False,
                                              "input": self._scrub(checks.show(args)),
                                              "expected": self._scrub(verdict.expected),
                                              "actual": self._scrub(verdict.actual)}
                    entry["first_failure"].update({name: self._scrub(getattr(verdict, name))  # checks' words
                                                   for name in ("difference", "tolerance") if getattr(verdict, name)})
                else:
                    entry["first_failure"] = {"check": behaviour.description, "hidden": True,
                                              "input": "a hidden input (not shown)"}
        entry["auto_earned"] = round(min(earned, info.auto), 2)
        entry["notes"].extend(_seen(todo, read, layout))
        for warning in dict.fromkeys(warnings):
            entry["notes"].append(f"warning (not a failure): {self._scrub(warning)}")
        return entry

    def _expected(self, case_id, behaviour, reference):
        if not behaviour.exact:
            return None
        if self.key is not None:
            return self.key["expected"].get(case_id)
        result = reference.get(case_id)
        return result["values"] if result else None

    def _reference_lines(self):
        """Lines of the reference's solutions, to keep them out of anything shown to a student."""
        if self.reference_bodies is None:
            return ()
        lines = set()
        for bodies in self.reference_bodies.values():
            for body in bodies:
                for line in body:
                    stripped = line.strip()
                    if len(stripped) >= 12 and not stripped.startswith("#"):
                        lines.add(stripped)
        return tuple(sorted(lines))

    def _scrub(self, text):
        text = str(text)
        if any(line in text for line in self._secret_lines):
            return "(not shown: it contains the reference solution's code)"
        return text


def _seen(todo, read, layout):
    """A note naming what the student's code for ``todo`` reaches for that a solution does not need."""
    if todo not in read.bodies or layout is None:
        return []
    module_level = any(block.module_level for file_blocks in layout.blocks_by_file.values()
                       for block in file_blocks if block.todo == todo)
    seen = sorted({name for body in read.bodies[todo] for name in blocks.scan_body(body, module_level)})
    if not seen:
        return []
    return [f"seen in your code for {todo}: {', '.join(seen)}. None of it can change a grade: your code runs "
            "in a sandbox and only the values it returns are compared, by the grader, with the reference's"]


def _missing(outcome, reason=None):
    if reason:
        return {"status": "error", "error": reason, "warnings": [], "values": {}}
    if outcome is None:
        return {"status": "error", "error": "not run", "warnings": [], "values": {}}
    why = outcome.detail if outcome.status != "ok" else "no answer"
    return {"status": "error", "error": f"not answered: {why}", "warnings": [], "values": {}}


def _clean_result(item):
    values = item.get("values") if isinstance(item.get("values"), dict) else {}
    clean = {}
    for name, value in values.items():
        array = np.asarray(value)
        if isinstance(name, str) and array.dtype.kind in "biuf":
            clean[name] = array
    status = item.get("status") if item.get("status") in ("ok", "error") else "error"
    return {"status": status, "error": str(item.get("error", ""))[:protocol.MAX_TEXT],
            "warnings": [str(w)[:protocol.MAX_TEXT] for w in (item.get("warnings") or [])[:3]] if
            isinstance(item.get("warnings"), list) else [], "values": clean}


# --------------------------------------------------------------------------------------------
# The answer key of the student edition
# --------------------------------------------------------------------------------------------


def _encode_array(array):
    array = np.asarray(array)
    return {"dtype": str(array.dtype), "shape": list(array.shape), "data": array.ravel().tolist()}


def _decode_array(data):
    return np.array(data["data"], dtype=data["dtype"]).reshape(data["shape"])


def _visible_digest(cases):
    return _digest(*[protocol.fingerprint({"id": case_id, "args": args})
                     for todo in sorted(cases) for case_id, _, args in cases[todo].visible])


def write_answer_key(reference_kit, out_path, python=None, isolation="auto"):
    """Write the answer key of the student edition: the reference's values for the VISIBLE
    inputs of the exact checks (nothing about hidden checks), as JSON at ``out_path``."""
    grader = Grader(reference_kit, python=python, isolation=isolation)
    expected = {}
    for todo in checks.GRADED_TODOS:
        cases = checks.CaseSet(todo, visible=grader.cases[todo].visible)
        if not any(behaviour.exact for _, behaviour, _ in cases.visible):
            continue
        files = blocks.composite_files(grader.layout, {todo: grader.reference_bodies[todo]}, set(checks.NEEDS[todo]),
                                       only=checks.SETTINGS_ONLY.get(todo))
        outcome, results = grader._run(files, cases.requests())
        for case_id, behaviour, _ in cases.visible:
            if behaviour.exact:
                result = results.get(case_id)
                if result is None or result["status"] != "ok":
                    raise GradingError(f"the reference fails visible check {case_id}: "
                                       f"{result['error'] if result else outcome.detail}")
                expected[case_id] = {name: _encode_array(value) for name, value in result["values"].items()}
    key = {"version": ANSWER_KEY_VERSION, "visible_cases": _visible_digest(grader.cases), "expected": expected}
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(key, sort_keys=True, separators=(",", ":")) + "\n", encoding="utf-8")
    return out_path


def read_answer_key(path):
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    if data.get("version") != ANSWER_KEY_VERSION:
        raise GradingError(f"{path}: answer key version {data.get('version')}, this grader reads {ANSWER_KEY_VERSION}")
    data["expected"] = {case_id: {name: _decode_array(value) for name, value in values.items()}
                        for case_id, values in data["expected"].items()}
    return data


def _check_key_matches(key, cases):
    if key.get("visible_cases") != _visible_digest(cases):
        raise GradingError("the answer key was written for other visible checks than this grader's: "
                           "rebuild the student edition (python -m instructor.release student OUT)")
