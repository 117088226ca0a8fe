"""The grader's protocol against a hostile worker, without a sandbox: the broker (``broker.run_cases``)
talks to scripted fake workers and a fake reference server, and the message format
(``channel.py``) reads forged archives. What the broker must do: number its requests, take one
reply per request and only when it is due, hold each answer to its probe's schema, keep the
worker's words for visible cases only, stop in fixed words, serve only the calls the TODO may
make, call back only what the call passed, and keep its own records of every episode.
"""

from __future__ import annotations

import io
import os
import struct
import time
import zipfile

import numpy as np
import pytest

from hwtools.grade import broker
from hwtools.grade.in_sandbox import channel, served


class FakeWorker:
    """A worker process as the broker sees it: ``script(message, fake)`` returns the messages the
    worker sends in answer to each message of the grader (in order); ``fake.sent`` keeps those."""

    def __init__(self, script):
        self.script, self.outbox, self.sent, self.deadline = script, [], [], time.monotonic() + 30

    def send(self, message):
        message = channel.unpack(channel.pack(message))  # what crosses is what the format carries
        self.sent.append(message)
        self.outbox.extend(self.script(message, self))

    def receive(self, deadline=None):
        if not self.outbox:
            return "ended:"
        reply = self.outbox.pop(0)
        return reply if isinstance(reply, str) else channel.unpack(channel.pack(reply))

    def finish(self, graceful=True):
        return (0 if graceful else -9), "", 0.1


class FakeServer:
    """A reference server: run_policy's reward is the seed mod 100; scalar_finite_diff calls its
    argument f back twice; anything else answers 1.0."""

    def __init__(self):
        self.calls, self.pending, self.broken, self.closed, self.sent = [], [], False, False, 0

    def send(self, message, deadline=None):  # numbers its messages, as ReferenceServer.send does
        self.sent += 1
        message = dict(message, n=self.sent)
        self.calls.append(message)
        if message["op"] == "call" and message["fn"] == "scalar_finite_diff":
            self.pending = [{"op": "callback", "k": 1, "cb": message["args"]["f"]["__callable__"], "args": [np.ones(2)]},
                            {"op": "callback", "k": 2, "cb": message["args"]["f"]["__callable__"], "args": [np.zeros(2)]},
                            {"op": "done", "re": message["n"], "status": "ok", "value": np.array([0.5, 0.5])}]
        elif message["op"] == "call":
            value = float(message["args"]["seed"] % 100) if message["fn"] == "run_policy" else 1.0
            self.pending = [{"op": "done", "re": message["n"], "status": "ok", "value": value,
                             "episodes": {"params": np.zeros((0, 4)), "seeds": np.zeros(0, dtype=np.int64),
                                          "rewards": np.zeros(0)}}]
        return self.sent

    def receive(self, deadline):
        return self.pending.pop(0)


class FakePool:
    def __init__(self):
        self.server = FakeServer()

    def acquire(self, need=0.0):
        return self.server

    def release(self, server, broken=False):
        pass


def answering(values_of):
    """A script that answers setup and every case correctly (``values_of(args)``)."""

    def script(message, fake):
        if message["op"] == "setup":
            return [{"op": "ready", "re": message["n"]}]
        if message["op"] == "case":
            return [{"op": "result", "re": message["n"], "status": "ok", "values": values_of(message["args"]),
                     "warnings": []}]
        return []

    return script


SIGMOID_CASES = [(f"2.2.1/values/v{i}", "sigmoid", {"z": np.array([float(i)])}) for i in range(2)]
HIDDEN_CASES = [(f"2.2.1/values/h{i}", "sigmoid", {"z": np.array([10.0 + i])}) for i in range(2)]


def sigmoid_values(args):
    return {"values": 1 / (1 + np.exp(-args["z"]))}


def test_a_worker_that_follows_the_protocol_has_every_answer_taken():
    fake = FakeWorker(answering(sigmoid_values))
    outcome, results = broker.run_cases(fake, "2.2.1", SIGMOID_CASES, HIDDEN_CASES, None)
    assert outcome.status == "ok" and outcome.phase == "done"
    assert [m["n"] for m in fake.sent] == [1, 2, 3, 4, 5, 6]  # numbered by the grader, one by one
    assert [m["op"] for m in fake.sent] == ["setup", "case", "case", "case", "case", "exit"]
    assert all(results[case_id]["status"] == "ok" for case_id, _, _ in SIGMOID_CASES + HIDDEN_CASES)


def test_hidden_cases_are_sent_only_after_every_visible_answer_was_taken():
    sent_before_answer = []

    def script(message, fake):
        if message["op"] == "case" and message["id"].endswith("v1"):
            sent_before_answer.extend(m["id"] for m in fake.sent if m["op"] == "case")
        return answering(sigmoid_values)(message, fake)

    broker.run_cases(FakeWorker(script), "2.2.1", SIGMOID_CASES, HIDDEN_CASES, None)
    assert not any("/h" in case_id for case_id in sent_before_answer)


@pytest.mark.parametrize("forgery", ["next request", "twice", "never asked", "as a bool", "no number"])
def test_an_answer_out_of_turn_stops_the_run(forgery):
    def script(message, fake):
        if message["op"] != "case":
            return answering(sigmoid_values)(message, fake)
        good = {"op": "result", "re": message["n"], "status": "ok", "values": sigmoid_values(message["args"]),
                "warnings": []}
        return {"next request": [dict(good, re=message["n"] + 1), good], "twice": [good, good],
                "never asked": [dict(good, re=99), good], "as a bool": [dict(good, re=True)],
                "no number": [{k: v for k, v in good.items() if k != "re"}]}[forgery]

    outcome, results = broker.run_cases(FakeWorker(script), "2.2.1", SIGMOID_CASES, HIDDEN_CASES, None)
    assert outcome.status == "violation" and outcome.detail == broker.STOPS["violation"]
    assert not any(case_id in results for case_id, _, _ in HIDDEN_CASES)  # the run stopped before them


@pytest.mark.parametrize("values", [{}, {"values": np.zeros(1), "extra": np.zeros(1)}, {"other": np.zeros(1)},
                                    {"values": np.zeros(1, dtype=np.int64)}, {"values": np.zeros((1,) * 5)},
                                    {"values": 0.5}, "not a dict"])
def test_an_answer_that_does_not_fit_its_schema_fails_its_case(values):
    def script(message, fake):
        if message["op"] == "case":
            return [{"op": "result", "re": message["n"], "status": "ok", "values": values, "warnings": []}]
        return answering(sigmoid_values)(message, fake)

    outcome, results = broker.run_cases(FakeWorker(script), "2.2.1", SIGMOID_CASES, [], None)
    assert outcome.status == "ok"
    assert all(result["status"] == "error" and "does not have the values" in result["error"] for result in results.values())


def test_the_workers_words_are_kept_for_visible_cases_only_and_cut():
    def script(message, fake):
        if message["op"] == "case":
            return [{"op": "result", "re": message["n"], "status": "error", "error": "E" * 5000 + "\x1b[2J",
                     "warnings": ["W\x07" * 10] * 9, "values": {}}]
        return answering(sigmoid_values)(message, fake)

    _, results = broker.run_cases(FakeWorker(script), "2.2.1", SIGMOID_CASES, HIDDEN_CASES, None)
    visible, hidden = results[SIGMOID_CASES[0][0]], results[HIDDEN_CASES[0][0]]
    assert len(visible["error"]) <= channel.MAX_TEXT and "\x1b" not in visible["error"]
    assert len(visible["warnings"]) == 3 and all("\x07" not in warning for warning in visible["warnings"])
    assert hidden["error"] == "" and hidden["warnings"] == [] and hidden["status"] == "error"


@pytest.mark.parametrize("ending, status", [("garbled:an answer of 123456789 bytes", "garbled"),
                                            ("timeout:the wall-clock limit was reached", "timeout"),
                                            ("ended:", "ended"), ("anything:else 42", "garbled")])
def test_a_stop_is_told_in_fixed_words(ending, status):
    def script(message, fake):
        return [ending] if message["op"] == "case" else answering(sigmoid_values)(message, fake)

    outcome, _ = broker.run_cases(FakeWorker(script), "2.2.1", SIGMOID_CASES, HIDDEN_CASES, None)
    assert outcome.status == status and not any(ch.isdigit() for ch in outcome.detail), outcome.detail


def calling(*calls):
    """A script whose first case makes ``calls`` ([(fn, args, state)]) one after the other, keeping
    the grader's replies, then answers; every later case is answered at once."""
    replies = []

    def script(message, fake):
        if message["op"] == "setup":
            return [{"op": "ready", "re": message["n"]}]
        if message["op"] == "case" and not replies and calls:
            fake.case = message["n"]
            return [{"op": "call", "k": 1, "fn": calls[0][0], "args": calls[0][1], "state": calls[0][2]}]
        if message["op"] == "reply":
            replies.append(message)
            if len(replies) < len(calls):
                fn, args, state = calls[len(replies)]
                return [{"op": "call", "k": len(replies) + 1, "fn": fn, "args": args, "state": state}]
            return [{"op": "result", "re": fake.case, "status": "ok", "values": {"value": np.float64(1.0),
                                                                                  "value_again": np.float64(1.0)}}]
        if message["op"] == "callback":
            return [{"op": "return", "re": message["n"], "status": "ok", "value": 3.0}]
        if message["op"] == "case":
            return [{"op": "result", "re": message["n"], "status": "ok",
                     "values": {"value": np.float64(1.0), "value_again": np.float64(1.0)}}]
        return []

    return script, replies


EVAL_CASE = [("1.3.1/mean-reward/v0", "eval_params", {"params": np.zeros(4), "num_rollouts": 2, "seed": 5})]


def test_run_policy_is_played_on_the_trusted_side_and_recorded_there():
    script, replies = calling(("run_policy", {"params": np.full(4, 0.5), "seed": 7, "env": None}, {}),
                              ("run_policy", {"params": np.full(4, 0.5), "seed": None, "env": None}, {}))
    pool = FakePool()
    outcome, results = broker.run_cases(FakeWorker(script), "1.3.1", EVAL_CASE, [], pool)
    records = results[EVAL_CASE[0][0]]["records"]
    assert outcome.status == "ok" and [r["status"] for r in replies] == ["ok", "ok"]
    assert records["episode_seeds"][0] == 7 and records["episode_seeded"].tolist() == [True, False]
    chosen = records["episode_seeds"][1]  # an unseeded episode gets a seed of the grader's choosing
    assert [c["args"]["seed"] for c in pool.server.calls if c["op"] == "call"] == [7, chosen]
    assert records["episode_rewards"].tolist() == [7.0, float(chosen % 100)]


def test_a_call_the_run_may_not_make_is_refused_in_the_graders_words():
    script, replies = calling(("predict_prob", {"X": np.zeros((2, 3))}, {"n_features": 3, "weights": np.zeros(4)}),
                              ("open_the_answers", {}, {}),
                              ("eval_params", {"params": "text", "num_rollouts": 1, "seed": 0}, {}),
                              ("eval_params", {"params": np.zeros(4), "num_rollouts": 1, "seed": 0, "extra": 1}, {}))
    outcome, _ = broker.run_cases(FakeWorker(script), "2.2.1", EVAL_CASE, [], FakePool())
    assert outcome.status == "ok"
    assert [(r["status"], r["type"]) for r in replies] == [("error", "NotImplementedError"),
                                                           ("error", "NotImplementedError"), ("error", "TypeError"),
                                                           ("error", "TypeError")]
    assert "computes what TODO 2.2.1 computes" in replies[0]["message"]
    assert "open_the_answers" not in replies[1]["message"]


def test_call_backs_go_to_the_function_the_call_passed_and_nothing_else():
    script, replies = calling(("scalar_finite_diff", {"f": {"__callable__": 0}, "x": np.zeros(2), "h": 0.5}, {}))
    fake = FakeWorker(script)
    outcome, _ = broker.run_cases(fake, "1.3.2", EVAL_CASE, [], FakePool())
    callbacks = [m for m in fake.sent if m["op"] == "callback"]
    assert outcome.status == "ok" and len(callbacks) == 2 and all(m["cb"] == 0 for m in callbacks)
    assert replies[0]["status"] == "ok" and replies[0]["value"].tolist() == [0.5, 0.5]


def test_a_known_objective_answers_eval_params_in_its_cases_and_every_evaluation_is_recorded():
    objective = {"A": np.eye(4), "m": np.ones(4), "q": np.full(4, 0.1), "c": 10.0}
    case = [("1.3.2/equation-4/v0", "train_known", {"objective": objective})]
    script, replies = calling(("eval_params", {"params": np.zeros(4), "num_rollouts": 3, "seed": 11}, {}),
                              ("eval_params", {"params": np.zeros(3), "num_rollouts": 3, "seed": 11}, {}))

    def answer(message, fake):  # a training run answers its own values
        out = script(message, fake)
        return [dict(item, values={"rewards": np.zeros(2), "params_history": np.zeros((2, 4)),
                                   "final_params": np.zeros(4)}) if item.get("op") == "result" else item for item in out]

    pool = FakePool()
    outcome, results = broker.run_cases(FakeWorker(answer), "1.3.2", case, [], pool)
    records = results[case[0][0]]["records"]
    assert outcome.status == "ok" and not pool.server.calls  # answered by the grader itself
    assert replies[0]["value"] == pytest.approx(10.0 - 4 - 0.4) and replies[1]["type"] == "ValueError"
    assert records["evaluation_rollouts"].tolist() == [3] and records["evaluation_seeds"].tolist() == [11]


def test_calls_numbered_out_of_order_stop_the_run():
    def script(message, fake):
        if message["op"] == "case":
            return [{"op": "call", "k": 2, "fn": "sigmoid", "args": {"z": np.zeros(1)}, "state": {}}]
        return answering(sigmoid_values)(message, fake)

    outcome, _ = broker.run_cases(FakeWorker(script), "2.2.3", SIGMOID_CASES, [], FakePool())
    assert outcome.status == "violation"


# --------------------------------------------------------------------------------------------
# The message format: nothing is inflated, nothing is believed
# --------------------------------------------------------------------------------------------


def test_messages_round_trip_with_their_types():
    message = {"a": np.arange(6.0).reshape(2, 3), "s": np.int64(3), "f": 0.1, "none": None, "l": [True, np.float32(2)]}
    back = channel.unpack(channel.pack(message))
    assert isinstance(back["s"], np.int64) and back["a"].shape == (2, 3) and back["f"] == 0.1 and back["none"] is None
    assert channel.pack(message) == channel.pack(message)  # no time stamps
    assert np.load(io.BytesIO(channel.pack(message)))["a0"].shape == (2, 3)  # an npz numpy reads


def _archive(members, compression=zipfile.ZIP_STORED):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _npy(array):
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.asarray(array))
    return buffer.getvalue()


META = _npy(np.frombuffer(b'{"x": {"__array__": "a0"}}', dtype=np.uint8))


REFUSALS = {"deflated": "compressed", "lying header": "does not match its bytes", "object dtype": "numbers only",
            "other name": "member this grader does not write", "extra bytes": "does not match its bytes",
            "too large": "larger than", "truncated": "no end record", "unicode structure": "numbers only",
            "comment": "no end record"}


@pytest.mark.parametrize("forgery", list(REFUSALS))
def test_a_forged_archive_is_refused_before_anything_is_inflated_or_allocated(forgery):
    lying = bytearray(_npy(np.zeros(4)))
    lying[lying.index(b"(4,)"):lying.index(b"(4,)") + 4] = b"(9,)"
    data = {
        "deflated": lambda: _archive({"__json__.npy": META, "a0.npy": _npy(np.zeros(100_000))}, zipfile.ZIP_DEFLATED),
        "lying header": lambda: _archive({"__json__.npy": META, "a0.npy": bytes(lying)}),
        "object dtype": lambda: _archive({"__json__.npy": META, "a0.npy": _npy(np.zeros(1)).replace(b"<f8", b"|O8")}),
        "other name": lambda: _archive({"__json__.npy": META, "../a0.npy": _npy(np.zeros(1))}),
        "extra bytes": lambda: _archive({"__json__.npy": META, "a0.npy": _npy(np.zeros(2)) + b"\0" * 8}),
        "too large": lambda: b"PK" + bytes(channel.MAX_MESSAGE_BYTES),
        "truncated": lambda: channel.pack({"x": np.zeros(3)})[:-30],
        "unicode structure": lambda: _archive({"__json__.npy": _npy(np.array('{"x": 1}')), "a0.npy": _npy(np.zeros(1))}),
        "comment": lambda: channel.pack({"x": np.zeros(3)})[:-2] + struct.pack("<H", 4) + b"abcd",
    }[forgery]()
    with pytest.raises(channel.MessageError, match=REFUSALS[forgery]):
        channel.unpack(data)


def test_the_call_schema_takes_numbers_only_and_bounds_them():
    entry = served.SERVED_BY_NAME["eval_params"]
    assert served.check_call(entry, {"params": [0.0] * 4, "num_rollouts": 3, "seed": 0}, {})[0] is None
    assert "up to 1000" in served.check_call(entry, {"params": np.zeros(4), "num_rollouts": 10**6, "seed": 0}, {})[0]
    assert "not numbers" in served.check_call(entry, {"params": "x", "num_rollouts": 3, "seed": 0}, {})[0]
    assert "takes the arguments" in served.check_call(entry, {"params": np.zeros(4)}, {})[0]
    sfd = served.SERVED_BY_NAME["scalar_finite_diff"]
    assert served.check_call(sfd, {"f": {"__callable__": 0}, "x": np.zeros(3), "h": 0.1}, {}) == (None, (0,))
    assert served.check_call(sfd, {"f": 1.0, "x": {"__callable__": 0}, "h": 0.1}, {})[0]  # only f may be a function
    big = np.zeros(served.MAX_NUMBERS + 1)
    assert "larger" in served.check_call(served.SERVED_BY_NAME["sigmoid"], {"z": big}, {})[0]


# --------------------------------------------------------------------------------------------
# Deadlines on writes too: a real worker process that stops reading
# --------------------------------------------------------------------------------------------

SILENT_RUNTIME = '''"""A hostile worker: it answers setup, reads its first case, makes one large served call and
then never reads again, so the grader's reply fills the pipe."""
import time

import numpy as np

from . import channel


def main(kit_dir, requests, answers):
    setup = channel.read_message(requests)
    channel.write_message(answers, {"op": "ready", "re": setup["n"]})
    channel.read_message(requests)
    channel.write_message(answers, {"op": "call", "k": 1, "fn": "sigmoid", "args": {"z": np.zeros(%d)}, "state": {}})
    time.sleep(3600)
'''
BIG = 200_000  # numbers: 1.6 MB each way, far more than a pipe holds


class BigServer(FakeServer):
    """A reference server whose answer to a call is as large as the call: BIG numbers."""

    def send(self, message, deadline=None):
        self.sent += 1
        self.pending = [{"op": "done", "re": self.sent, "status": "ok", "value": np.zeros(BIG)}]
        return self.sent


def test_a_worker_that_stops_reading_is_killed_at_the_run_s_wall_limit(tmp_path, monkeypatch):
    """The grader's reply to a large served call fills the pipe of a worker that no longer reads: the
    write ends at the run's deadline (a blocking write waited for ever), the run stops as timed out
    and the worker is killed. (With 3 s of slack in the wall limit, not WALL_SLACK's 10: the deadline is
    what is tested, not its size.)"""
    import threading

    from hwtools.grade import kits, sandbox

    monkeypatch.setattr(sandbox, "WALL_SLACK", 3.0)

    kit = tmp_path / "kit"
    for relative, text in kits.sandboxed_files().items():
        (kit / relative).parent.mkdir(parents=True, exist_ok=True)
        (kit / relative).write_text(text)
    (kit / "_hwgrade" / "runtime.py").write_text(SILENT_RUNTIME % BIG)
    box = sandbox.Sandbox(isolation="none", time_limit=1)
    pool = FakePool()
    pool.server = BigServer()
    process = box.start(kit)
    ended = []
    thread = threading.Thread(target=lambda: ended.append(broker.run_cases(
        process, "2.2.3", [("2.2.3/big/v0", "sigmoid", {"z": np.zeros(BIG)})], [], pool)), daemon=True)
    started = time.monotonic()
    thread.start()
    thread.join(timeout=sandbox.wall_limit(1) + 20)
    try:
        assert ended, f"the grader was still writing to a worker that stopped reading after {time.monotonic() - started:.0f} s"
        outcome, results = ended[0]
        assert outcome.status == "timeout" and outcome.detail == broker.TIMEOUTS["the wall-clock limit of"]
        assert time.monotonic() - process.started < sandbox.wall_limit(1) + 10  # from the run's begin: not the lock's wait
        assert process.process.poll() is not None, "the worker that stopped reading was not killed"
        assert results == {}
    finally:
        if process.process.poll() is None:
            os.killpg(process.process.pid, 9)


def test_an_answer_or_a_served_call_larger_than_its_case_needs_is_refused_before_it_is_kept():
    """Sizes follow the case: an answer holds at most 4 x its input's numbers + 256, a served call
    (and the reference's reply) at most 2 x + 1,024; a larger one is refused, not stored."""
    case = [("2.2.1/values/v0", "sigmoid", {"z": np.zeros(10)})]
    assert broker.answer_limit(case[0][2]) == 4 * 10 + 256 and broker.call_limit(case[0][2]) == 2 * 10 + 1024

    def big_answer(message, fake):
        if message["op"] == "case":
            return [{"op": "result", "re": message["n"], "status": "ok", "values": {"values": np.zeros(297)}}]
        return answering(sigmoid_values)(message, fake)

    outcome, results = broker.run_cases(FakeWorker(big_answer), "2.2.1", case, [], None)
    assert outcome.status == "ok" and results[case[0][0]]["values"] == {}
    assert "far more numbers than this check's input" in results[case[0][0]]["error"]
    fits = lambda message, fake: [{"op": "result", "re": message["n"], "status": "ok",  # noqa: E731
                                   "values": {"values": np.zeros(296)}}] if message["op"] == "case" \
        else answering(sigmoid_values)(message, fake)
    assert broker.run_cases(FakeWorker(fits), "2.2.1", case, [], None)[1][case[0][0]]["status"] == "ok"

    script, replies = calling(("sigmoid", {"z": np.zeros(2 * 10 + 1025)}, {}), ("sigmoid", {"z": np.zeros(3)}, {}))
    outcome, _ = broker.run_cases(FakeWorker(script), "2.2.3", case, [], FakePool())
    assert [r["status"] for r in replies] == ["error", "ok"]
    assert "larger than the grader serves in this check" in replies[0]["message"]


# --------------------------------------------------------------------------------------------
# The trusted side's work is bounded: judging is linear in what was recorded, with a cap
# --------------------------------------------------------------------------------------------


def real_training_records(copies, iterations=2):
    """A real 1.3.2 run that follows eq. (4), whose records hold every evaluation at theta +- h e_i
    ``copies`` times (one seed): the case that made the judge pair every copy with every other."""
    from hwtools.grade.checks import p1_cartpole

    args = p1_cartpole.make_real_training(np.random.default_rng(0), 0)
    args["iterations"] = iterations
    h, rate = args["fd_step"], args["learning_rate"]
    theta, history, rewards, points, scores = np.asarray(args["initial_params"], dtype=np.float64), [], [0.0], [], []
    history.append(theta)
    for t in range(iterations):
        gradient = np.zeros(4)
        for i in range(4):
            step = np.eye(4)[i] * h
            for _ in range(copies):
                points += [theta + step, theta - step]
                scores += [100.0 + i, 90.0]
            gradient[i] = (100.0 + i - 90.0) / (2 * h)
        theta = theta + rate * gradient
        points.append(theta)
        scores.append(50.0 + t)
        history.append(theta)
        rewards.append(50.0 + t)
    records = broker.Records().arrays() | {
        "evaluation_params": np.array(points), "evaluation_seeds": np.full(len(points), 7),
        "evaluation_rollouts": np.full(len(points), args["rollouts"]), "evaluation_values": np.array(scores)}
    values = {"params_history": np.array(history), "rewards": np.array(rewards), "final_params": theta}
    return args, {"status": "ok", "values": values, "records": records}


def test_the_real_run_judge_of_1_3_2_is_linear_in_its_records_and_capped():
    from hwtools.grade.checks import p1_cartpole

    args, result = real_training_records(1)
    assert p1_cartpole.judge_real_rewards(args, result, None, []).passed
    wrong = dict(result, values=dict(result["values"], rewards=result["values"]["rewards"] + [0, 0, 1]))
    assert "is no evaluation of theta[2]" in p1_cartpole.judge_real_rewards(args, wrong, None, []).actual
    args, result = real_training_records(p1_cartpole.MAX_JUDGED_EVALUATIONS // 18)  # just under the cap
    started = time.process_time()
    assert p1_cartpole.judge_real_rewards(args, result, None, []).passed
    assert time.process_time() - started < 2.0, "the judge paired every recorded evaluation with every other"
    args, result = real_training_records(p1_cartpole.MAX_JUDGED_EVALUATIONS)
    started = time.process_time()
    verdict = p1_cartpole.judge_real_rewards(args, result, None, [])
    assert not verdict.passed and "more than the 2000 this check reads" in verdict.actual
    assert time.process_time() - started < 2.0


def test_the_graders_threads_parse_students_code_one_at_a_time(monkeypatch):
    """The grader judges a submission's TODOs in threads, and CPython 3.11's AST builder keeps its
    recursion count per interpreter (gh-106905): two threads in ``ast.parse`` at once can fail with
    "SystemError: AST constructor recursion depth mismatch" (seen in CI). A garbage-collector
    callback that yields the GIL makes the threads meet inside the parser; ``blocks.parse`` must
    never fail (with its lock replaced by a no-op, this test fails)."""
    import gc
    import threading

    from hwtools.grade import blocks

    source = "\n".join(f"def f{i}(x):\n    return [(x, {{'a': (x, [x])}}) for _ in range(3)]" for i in range(200))
    errors = []

    def yield_gil(phase, info):
        if phase == "start":
            time.sleep(0)

    def parse_often():
        for _ in range(40):
            try:
                blocks.parse(source)
            except SystemError as error:
                errors.append(str(error))

    threshold = gc.get_threshold()
    gc.callbacks.append(yield_gil)
    gc.set_threshold(50)
    try:
        threads = [threading.Thread(target=parse_often) for _ in range(3)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    finally:
        gc.callbacks.remove(yield_gil)
        gc.set_threshold(*threshold)
    assert errors == []


@pytest.mark.parametrize("left, status", [({"op": "result", "re": 1}, "violation"), ("ended:", "ended")])
def test_a_message_left_by_a_worker_that_is_gone_is_out_of_turn(left, status):
    """A worker that answers, sends a forged answer and exits before the grader's next request (the
    request's write then fails) broke the protocol, however the machine's load orders the two; one that
    left nothing simply ended."""

    class Gone:
        def send(self, message):
            raise BrokenPipeError

        def receive(self):
            return left

    with pytest.raises(broker.Stop) as stop:
        broker.Conversation(Gone(), None, None).send({"op": "case"})
    assert stop.value.status == status
