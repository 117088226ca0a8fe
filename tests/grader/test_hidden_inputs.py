"""What a student sees carries no bit of a hidden input, and no wrong value keeps more than 30% (issue 30).

The visible-only view (the check cells, Gradescope's visible test, feedback before the grades are
out) is built from visible verdicts and visible notes alone (``judging.visible_view``): it shows the
first visible failure whatever hidden inputs did, and no note a hidden verdict caused (the 30%
cap's, a run stopped in its hidden phase).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from hwtools.check_cell import check_lines
from hwtools.grade import broker, checks, judging
from hwtools.grade.instructor.class_feedback import todo_markdown
from hwtools.grade.checks.verdicts import show
from hwtools.grade.instructor.gradescope_autograder import _tests

pytestmark = pytest.mark.timeout(120)


def _sigmoid(z):
    return 0.5 * (1.0 + np.tanh(np.asarray(z, dtype=np.float64) / 2.0))


class _Hidden:
    """A hidden-checks module with one hand-made hidden input per behaviour of 2.2.1."""

    @staticmethod
    def hidden_cases(behaviour):
        return [{"z": np.array([4242.0, -3.0, 0.5])}]


def _entry(wrong, stop_in_hidden=False):
    """2.2.1's entry judged on answers that are right except where ``wrong(case_id)`` says."""
    cases = checks.case_set("2.2.1", _Hidden)
    results, reference = {}, {}
    for case_id, _, args in cases.visible + cases.hidden:
        reference[case_id] = {"values": _sigmoid(args["z"])}
        values = _sigmoid(args["z"]) + (0.25 if wrong(case_id) else 0.0)
        results[case_id] = {"status": "ok", "values": {"values": values}, "warnings": []}
    outcome = broker.Outcome(status="ok", phase="done")
    if stop_in_hidden:
        outcome = broker.Outcome(status="timeout", detail="the time limit was reached", phase="hidden")
        for case_id, _, _ in cases.hidden:
            results.pop(case_id)
    run = {"student": (outcome, results), "reference": reference}
    return judging.judge_todo("2.2.1", run, {}, cases, lambda case_id, behaviour, ref: ref.get(case_id), str,
                              (5, 1024), [])


def _views(entry):
    tests = _tests({"todos": [entry]})
    visible_test = next(test for test in tests if test["visibility"] == "visible" and test["number"].startswith("2.2.1"))
    return {"check cell": "\n".join(check_lines(entry)), "Gradescope's visible test": visible_test["output"],
            "visible-only Markdown": todo_markdown(entry, visible_only=True), "status": visible_test["status"]}


def test_the_visible_view_shows_the_first_visible_failure_whatever_a_hidden_one_did():
    # "values" fails only on its hidden input, "any-shape" (after it) on a visible one
    entry = _entry(lambda case_id: case_id.startswith("2.2.1/values/h") or case_id == "2.2.1/any-shape/v1")
    assert entry["first_failure"]["hidden"], "the full entry's first failure is the hidden one"
    view = judging.visible_view(entry)
    assert view["first_failure"]["check"] == entry["checks"][1]["check"] and not view["first_failure"]["hidden"]
    assert [check["passed"] for check in view["checks"]] == [True, False, True]
    # the same view whether or not the hidden input failed: no bit of it reaches the student
    twin = _entry(lambda case_id: case_id == "2.2.1/any-shape/v1")
    for name, shown in _views(entry).items():
        assert shown == _views(twin)[name], name
    assert "hidden" not in _views(entry)["check cell"]


def test_the_visible_view_shows_no_note_a_hidden_verdict_caused():
    capped = _entry(lambda case_id: case_id.startswith("2.2.1/values/h"))  # a value wrong on a hidden input only
    assert capped["auto_earned"] == 0.6 and any("30%" in note for note in capped["notes"]), "a wrong value keeps 30%"
    for name, shown in _views(capped).items():
        assert shown == _views(_entry(lambda case_id: False))[name], name
    stopped = _entry(lambda case_id: False, stop_in_hidden=True)
    right = _entry(lambda case_id: False)
    assert stopped["status"] != "graded" and any("stopped" in note for note in stopped["notes"])
    for name, shown in _views(stopped).items():
        assert shown == _views(right)[name], name


def _scores(args):
    X = np.hstack([np.asarray(args["X"]), np.ones((len(args["X"]), 1))])
    return X @ np.asarray(args["weights"])


@pytest.mark.parametrize("behaviour", ["2.2.2/with-bias", "2.2.3/from-weights"])
def test_scores_pass_a_naive_sigmoids_overflow_on_both_signs_on_visible_and_hidden_inputs(behaviour):
    from hwtools.grade.grader import KIT_ROOT, load_hidden_checks

    cases = checks.case_set(behaviour[:5], load_hidden_checks(KIT_ROOT))
    for phase in (cases.visible, cases.hidden):
        scores = np.concatenate([_scores(args) for case_id, _, args in phase if case_id.startswith(behaviour)])
        assert scores.max() > 709 and scores.min() < -709, (behaviour, scores.min(), scores.max())


def test_1_1_1_has_scores_near_the_decision_boundary_on_visible_and_hidden_inputs():
    from hwtools.grade.grader import KIT_ROOT, load_hidden_checks

    cases = checks.case_set("1.1.1", load_hidden_checks(KIT_ROOT))
    for phase in (cases.visible, cases.hidden):
        for case_id, _, args in phase:
            scores = np.einsum("ij,ij->i", args["params"], args["obs"])
            near = scores[(np.abs(scores) > 1e-6) & (np.abs(scores) < 1e-2)]
            if case_id.endswith("/h2"):  # the hand-chosen ties
                continue
            assert (near > 0).any() and (near < 0).any(), case_id


def test_hidden_inputs_are_drawn_per_grading_and_again_the_same_for_its_secret():
    from hwtools.grade import Grader
    from hwtools.grade.grader import KIT_ROOT, is_secret

    grader = Grader(KIT_ROOT)
    try:
        ours, again, other = "0" * 32, "0" * 32, "f" * 32
        first, regrade, later = (grader.case_set("2.2.1", secret) for secret in (ours, again, other))
        assert [c for c, _, _ in first.visible] == [c for c, _, _ in later.visible]
        visible = {c: show(args) for c, _, args in first.visible}
        assert visible == {c: show(args) for c, _, args in later.visible}, "visible inputs are the same for everyone"
        shown = [show(args) for _, _, args in first.hidden]
        assert shown == [show(args) for _, _, args in regrade.hidden], "a regrade with the stored secret draws the same"
        drawn = [show(args) for _, _, args in later.hidden]
        assert len(shown) == len(drawn) and all(a != b for a, b in zip(shown, drawn)), "another grading, other inputs"
        # and the hand-chosen ones keep their structure: the hidden 1.1.1 ties still score exactly 0
        for secret in (ours, other):
            *_, ties = [args for c, _, args in grader.case_set("1.1.1", secret).hidden if c.startswith("1.1.1/equation-1/")]
            assert not np.einsum("ij,ij->i", ties["params"], ties["obs"]).any()
        with pytest.raises(ValueError, match="secret"):
            grader.grade(KIT_ROOT, todos=["2.2.1"], secret="not hex")
    finally:
        grader.close()
    assert all(is_secret(secret) for secret in (ours, other)) and not is_secret("0" * 31) and not is_secret(None)


def _stable_sigmoid(z):
    with np.errstate(under="ignore"):
        decay = np.exp(-np.abs(z))
    return np.where(z >= 0, 1.0 / (1.0 + decay), decay / (1.0 + decay))


def _key(z):
    """How the typed-in 2.2.1 below looks an input up: its float64 bytes and shape."""
    z = np.asarray(z, dtype=np.float64)
    return z.tobytes().hex() + repr(z.shape)


TYPED_IN = """import json, pathlib
table = json.loads(pathlib.Path({path!r}).read_text())
values = np.asarray(table.get(z.tobytes().hex() + repr(z.shape), np.zeros(z.shape).tolist()), dtype=np.float64)"""


def test_typed_in_answers_for_an_earlier_grading_s_hidden_inputs_earn_nothing(tmp_path, monkeypatch):
    """Issue 42's attack: a 2.2.1 that computes nothing, its answers typed in (here a table the block
    reads, standing in for the page cache that carried them from another TODO's block: its code never
    changes) for the visible inputs, which are public, and for the hidden inputs an earlier grading
    sent to its hidden run (recorded here as a relay would carry them out). Graded again, it earns
    nothing: each grading draws its hidden inputs from a secret of its own. Against the grader that
    drew them from the TODO's code alone, the second grading earned 2 of 2. A regrade that passes the
    first grading's secret back draws the first grading's inputs again."""
    from hwtools.grade import Grader, blocks, kits
    from hwtools.grade import grader as grading
    from hwtools.grade.grader import KIT_ROOT

    sent, real = [], broker.run_cases

    def recorded(process, todo, visible, hidden, pool):
        sent.extend(args for _, _, args in hidden)
        return real(process, todo, visible, hidden, pool)

    monkeypatch.setattr(grading.broker, "run_cases", recorded)
    table = tmp_path / "answers.json"
    typed = {_key(args["z"]): _stable_sigmoid(np.asarray(args["z"], dtype=np.float64)).tolist()
             for _, _, args in checks.case_set("2.2.1").visible}
    table.write_text(json.dumps(typed), encoding="utf-8")
    kits.write_submission(blocks.load_layout(KIT_ROOT), tmp_path / "kit", {"2.2.1": TYPED_IN.format(path=str(table))},
                          others="reference")
    with Grader(KIT_ROOT, isolation="none", time_limit=20) as grader:  # the table is the stand-in relay: readable
        first, = grader.grade(tmp_path / "kit", todos=["2.2.1"])["todos"]
    assert all(check["failed_on"] != "visible" for check in first["checks"]), first  # the visible ones typed in
    earlier, sent[:] = list(sent), []
    assert earlier, "the first grading sent hidden inputs"
    typed.update({_key(args["z"]): _stable_sigmoid(np.asarray(args["z"], dtype=np.float64)).tolist()
                  for args in earlier})
    table.write_text(json.dumps(typed), encoding="utf-8")  # what the relay carried, typed in
    with Grader(KIT_ROOT, isolation="none", time_limit=20) as grader:  # a later grading (another process, a resubmission)
        result = grader.grade(tmp_path / "kit", todos=["2.2.1"])
        second, = result["todos"]
        assert second["auto_earned"] == 0, second
        assert all(check["failed_on"] == "hidden" for check in second["checks"]), second
        assert sent and all(_key(args["z"]) not in {_key(e["z"]) for e in earlier} for args in sent), "none drawn again"
        sent[:] = []
        regrade = grader.grade(tmp_path / "kit", todos=["2.2.1"], secret=result["secret"])
        assert [_key(args["z"]) for args in sent] == [_key(args["z"]) for args in _hidden_sent_of(grader, result)]
        assert regrade["todos"][0]["checks"] == second["checks"], "a regrade of the same code: the same verdicts"


def _hidden_sent_of(grader, result):
    return [args for _, _, args in grader.case_set("2.2.1", result["secret"]).hidden]


def test_every_visible_run_of_a_submission_comes_before_any_hidden_run(tmp_path, monkeypatch):
    """No run that can still send text back to the student begins after a run that saw a hidden input."""
    from hwtools.grade import Grader, blocks, kits
    from hwtools.grade import grader as grading
    from hwtools.grade.grader import KIT_ROOT

    runs, real = [], broker.run_cases

    def recorded(process, todo, visible, hidden, pool):
        runs.append((todo, bool(visible), bool(hidden)))
        return real(process, todo, visible, hidden, pool)

    monkeypatch.setattr(grading.broker, "run_cases", recorded)
    layout = blocks.load_layout(KIT_ROOT)
    kits.write_submission(layout, tmp_path, {"2.2.1": "values = 0.5 * (1 + np.tanh(z / 2))"}, others="reference")
    with Grader(KIT_ROOT) as grader:
        result = grader.grade(tmp_path, todos=["1.1.1", "2.2.1", "2.2.2"])
    assert [entry["auto_earned"] for entry in result["todos"]] == [2, 2, 3], result
    assert not any(visible and hidden for _, visible, hidden in runs), runs
    first_hidden = next(number for number, (_, _, hidden) in enumerate(runs) if hidden)
    assert all(hidden for _, _, hidden in runs[first_hidden:]), runs
    assert {todo for todo, visible, _ in runs if visible} == {todo for todo, _, hidden in runs if hidden}, runs


def test_a_visible_run_s_notes_reach_the_visible_view_and_a_hidden_run_s_do_not(tmp_path, monkeypatch):
    """A TODO with hidden cases is run twice (visible, then hidden): the visible-only view shows the
    notes its visible run produced, and none that only its hidden run produced."""
    from hwtools.grade import Grader, blocks, kits
    from hwtools.grade.grader import KIT_ROOT

    real = broker.Conversation.ask

    def ask(self, message, wanted):  # a note per case, as a served call's failure would leave one
        if message.get("op") == "case":
            self.notes.append(f"a note of the {'hidden' if '/h' in message['id'] else 'visible'} run")
        return real(self, message, wanted)

    monkeypatch.setattr(broker.Conversation, "ask", ask)
    layout = blocks.load_layout(KIT_ROOT)
    kits.write_submission(layout, tmp_path, {"2.2.1": "values = 0.5 * (1 + np.tanh(z / 2))"}, others="stub")
    with Grader(KIT_ROOT) as grader:
        entry, = grader.grade(tmp_path, todos=["2.2.1"])["todos"]
    assert entry["auto_earned"] == 2
    assert {"a note of the visible run", "a note of the hidden run"} <= set(entry["notes"]), entry["notes"]
    assert judging.visible_view(entry)["notes"] == ["a note of the visible run"]
    for name, shown in _views(entry).items():
        if name != "status":
            assert "a note of the visible run" in shown and "hidden run" not in shown, (name, shown)


def test_the_relay_hidden_cheat_shows_no_hidden_input_under_the_user_fallback(tmp_path):
    """The relay_hidden cheat (``cheats/relay_hidden.txt``) where runs share places: under the user
    fallback (Gradescope's), graded twice as a regrade of the same code (the same hidden inputs).
    2.2.1's hidden run leaves its inputs in every shared place it can write; 2.2.2's visible run,
    which comes before any hidden run of its grading and after the first grading's hidden runs,
    finds nothing to show, since a run makes no file (the seccomp filter, ``confine.py``): no hidden
    input of the submission reaches the feedback or results.json, and 2.2.2 keeps its points.
    (Under bubblewrap every place a run may write is its own: test_grading grades the cheat there.)"""
    import threading

    import containers
    import test_grading as proof
    from cheats import leak_search
    from hwtools.grade import Grader, blocks
    from hwtools.grade.grader import KIT_ROOT

    folder, python = containers.user_sandbox_python()
    layout, submission = blocks.load_layout(KIT_ROOT), tmp_path / "submission"
    proof.build_cheat(layout, proof.parse_cheat(proof.CHEATS / "relay_hidden.txt"), submission, None)
    relays = [Path(place, f"hwgrade-relay-hidden-{proof.CHANNEL}") for place in ("/tmp", "/var/tmp", "/dev/shm", "/run/lock")]
    seen, stop = set(), threading.Event()

    def watch():  # a file the cheat made would live at least as long as its run
        while not stop.wait(0.005):
            seen.update(str(path) for path in relays if path.exists())

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        gradings = []
        with containers.hidden_from_pool(KIT_ROOT):
            for _ in range(2):
                with Grader(KIT_ROOT, python=python, isolation="user", time_limit=10) as grader:
                    assert grader.sandbox.kind == "user", grader.sandbox.how
                    grader.wrong_solutions = []  # no known mistake to name: their runs are no part of this proof
                    regrade = gradings[0][0]["secret"] if gradings else None  # the second: the first's inputs again
                    result = grader.grade(submission, todos=["2.2.1", "2.2.2"], secret=regrade)
                    gradings.append((result, leak_search.secrets_of(grader, layout, grader.case_sets(result["secret"]))))
        assert not seen, f"the cheat made {sorted(seen)}"
        for result, secrets in gradings:
            leak_search.assert_nothing_leaks(result, secrets)
        for result, _ in gradings:  # nor anything of another run: 2.2.2's visible checks pass
            assert "RELAYED" not in json.dumps(result)
            assert [entry["auto_earned"] for entry in result["todos"]] == [0, 3], result["todos"]
    finally:
        stop.set()
        watcher.join(timeout=5)
        for path in relays:
            path.unlink(missing_ok=True)
        shutil.rmtree(folder, ignore_errors=True)


HIDDEN_ONLY = """import hashlib
values = np.where(z >= 0, 1.0 / (1.0 + np.exp(-np.abs(z))), np.exp(-np.abs(z)) / (1.0 + np.exp(-np.abs(z))))
if hashlib.sha256(z.tobytes() + repr(z.shape).encode()).hexdigest() not in {visible!r}:
{misbehave}"""
MISBEHAVIOURS = {
    "times out": "    while True:\n        pass",
    "fails": "    values = values + 0.25",
    "takes longer": "    import time\n    time.sleep(0.3)",
}


def before_publication(result):
    """What a student reads of ``result`` before the grades are published: results.json but for its
    ``score`` (Gradescope shows no total while a test is not yet visible: "If test cases are hidden,
    students will not be able to see their total score", its specification), the tests that are not
    ``visible`` and ``extra_data`` (stored for instructors); and the class feedback's status line and
    notes, which come before its points."""
    from hwtools.grade.instructor.class_feedback import feedback_markdown
    from hwtools.grade.instructor.gradebook import StudentResult, status_of
    from hwtools.grade.instructor.gradescope_autograder import results_json

    data = results_json(result, status_of(result), seconds=result["seconds"])
    shown = {key: value for key, value in data.items() if key not in ("score", "tests", "extra_data")}
    shown["tests"] = [test for test in data["tests"] if test.get("visibility", data.get("visibility")) == "visible"]
    shown["class feedback"] = feedback_markdown(StudentResult("s", status_of(result), result)).split("Automatic points")[0]
    return shown


def test_what_a_hidden_phase_does_changes_nothing_shown_before_publication(tmp_path):
    """Issue 42.3: a 2.2.1 right on every visible input that, on its hidden inputs only, runs until
    its time limit, answers wrongly or sleeps 0.3 s each, gives before publication exactly what a
    right one gives: the status line (before: "timed out: 2.2.1" for the first), the top-level
    output and notes, the visible tests, no run time. After publication its points and its TODO's
    test say what happened."""
    from hwtools.grade import Grader, blocks, kits
    from hwtools.grade.grader import KIT_ROOT

    visible = sorted(hashlib.sha256(np.asarray(args["z"], dtype=np.float64).tobytes()
                                    + repr(np.shape(args["z"])).encode()).hexdigest()
                     for _, _, args in checks.case_set("2.2.1").visible)
    layout, shown = blocks.load_layout(KIT_ROOT), {}
    with Grader(KIT_ROOT, time_limit=3, budget=120) as grader:  # a loaded machine slows runs: no budget time-out
        for name, misbehave in {"right": "    pass", **MISBEHAVIOURS}.items():
            code = HIDDEN_ONLY.format(visible=set(visible), misbehave=misbehave)
            kits.write_submission(layout, tmp_path / name, {"2.2.1": code}, others="reference")
            result = grader.grade(tmp_path / name, todos=["2.2.1"])
            entry, = result["todos"]
            assert entry["auto_earned"] == {"times out": 0, "fails": 0}.get(name, 2), (name, entry)
            shown[name] = (before_publication(result), entry, result["seconds"])
    assert shown["times out"][1]["status"] == "time limit" and shown["fails"][1]["checks"][0]["failed_on"] == "hidden"
    assert shown["takes longer"][2] > shown["right"][2] + 1.0, "the hidden phase took longer"
    for name in MISBEHAVIOURS:
        assert shown[name][0] == shown["right"][0], name
    assert "Status: **graded**" in shown["times out"][0]["output"]
