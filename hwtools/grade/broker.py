"""The grader's side of one run: it talks to a student's worker as to a hostile party, and keeps the records.

``run_cases`` drives one worker process (``Sandbox.start``) through the cases of one TODO: the
visible ones first, then, only once each of those is answered, the hidden ones. The rules:

* every message the grader sends carries its number; a reply must name the number it answers
  (``re``), come when it is asked for, and come once. Anything else (an answer out of turn, a
  second answer, a reply to a request never made, a message that does not parse) stops the run:
  the cases not yet answered fail. The stop is told in fixed words (``STOPS``), never a number
  or text of the worker's choosing.
* an answer must fit its probe's schema (``probes.RESULTS``: names, dtype kinds, dimensions) and
  hold at most ``answer_limit(args)`` numbers (4 x its case's input, plus 256), checked before it is
  kept; a served call and the reference's reply to it at most ``call_limit(args)`` (2 x the
  case's input, plus 1,024). A message is bounded by ``in_sandbox/channel.py`` before anything is decoded.
* every write to the worker, like every read, ends at the run's deadline (``Sandbox``): a worker
  that stops reading while the grader replies is stopped as timed out and killed.
* the worker's words (errors, warnings) are kept, cut to one line, for visible cases only. Once
  a hidden input was sent, nothing the worker says is kept but the status and numbers of its
  answers, which only the grader's verdict reaches.
* while a case runs, the worker may call functions of other TODOs (``served.plan``): the grader
  checks the call (``served.check_call``), has the reference server answer it, and calls back
  the functions the call passed, bounded in number. Every CartPole episode is played on the
  trusted side: ``run_policy`` by the reference server, with the grader's own seed where the
  call gave none (or in the call's ``gym.make`` environment), and every ``reset`` and ``step``
  of a ``gym.make("CartPole-v1")`` environment the code plays itself (``in_sandbox/served_env.py``); in
  ``train_known`` cases ``eval_params`` is the known objective, computed here. The grader
  records each episode, whatever door it came through (``episodes.py``: parameters or the
  actions taken, seed, start state, reward), and each evaluation (parameters, rollouts, seed,
  value) per case (``result["records"]``); the 1.3.x judges read only these records.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass, field

import numpy as np

from hwtools.grade.in_sandbox import channel, probes, served, served_env
from hwtools.grade.episodes import (  # noqa: F401 - Records: the records' type, given here too
    EVALUATION, IN_ENV, MAX_STEPS, RUN_POLICY, Environments, Episode, Records, start_of,
)
from hwtools.grade.reference import ServerFailed, ServerTimeout

MAX_CALLS = 50_000  # served calls per run
MAX_CALLBACKS = 50_000
MAX_EPISODES = 20_000
MAX_NESTING = 8  # calls within call-backs within calls...
KNOWN_OBJECTIVE = {"train_known"}  # probes whose eval_params is the case's known objective
STOPS = {
    "timeout": "the time limit was reached",
    "ended": "the worker process ended before answering",
    "garbled": "the worker sent something that is not a valid message",
    "violation": "the worker broke the protocol (an answer out of turn, a second answer, or one to a request "
                 "never made)",
    "lost": "the grading's sandbox was lost before this run, so it did not run (grade again)",
}
TIMEOUTS = {"the CPU-time limit": "the CPU-time limit was reached",  # the launcher's words, without its numbers
            "the wall-clock limit of": "the wall-clock limit was reached (the code waited)",
            "the submission's time budget": "the submission's time budget was used up by its earlier runs"}
_SIGNALS = {9: "killed (a limit was reached)", 24: "the CPU-time limit", 25: "the file-size limit (too much output?)",
            11: "a crash (segmentation fault)", 6: "an abort"}


class Stop(Exception):
    """The run ends here; ``status`` is a key of STOPS, ``detail`` a value of TIMEOUTS or empty."""

    def __init__(self, status, detail=""):
        super().__init__(status)
        self.status, self.detail = status, detail


def _stop(ending):
    """The Stop of a launcher's "status:detail": the detail only as one of the fixed TIMEOUTS."""
    status, _, detail = ending.partition(":")
    if status not in STOPS:
        return Stop("garbled")
    return Stop(status, next((words for start, words in TIMEOUTS.items() if detail.startswith(start)), "")
                if status == "timeout" else "")


@dataclass
class Outcome:
    """How a run ended: ``status`` ok or a key of STOPS, ``detail`` in the grader's words, ``phase``
    where it stopped (setup, visible, hidden, done), ``notes`` (fixed phrases), ``visible_notes``
    those of them given before any hidden input was sent (what a student may see)."""

    status: str = "ok"
    detail: str = ""
    phase: str = "setup"
    seconds: float = 0.0
    exit_code: int | None = None
    notes: list = field(default_factory=list)
    visible_notes: list = field(default_factory=list)
    stderr_tail: str = ""  # the worker's error stream (its prints): for the instructor's debugging, never shown
    budget: bool = False  # stopped by the submission's time budget (not by this code's own limits)


def _error(kind, message):
    return {"status": "error", "type": kind, "message": message}


def size(value, depth=0):
    """How many numbers ``value`` (case arguments, an answer: dicts, lists, arrays, scalars) holds."""
    if depth > channel.MAX_DEPTH:
        return 0
    if isinstance(value, dict):
        return sum(size(item, depth + 1) for item in value.values())
    if isinstance(value, (list, tuple)):
        return sum(size(item, depth + 1) for item in value)
    if isinstance(value, (np.ndarray, np.generic)):
        return int(np.size(value))
    return 1 if isinstance(value, (bool, int, float)) else 0


def call_limit(args):
    """The numbers a served call, or the reference's reply to it, may hold in a case on ``args``:
    no call a solution makes works on more than its case's data (twice it, for the constant column)."""
    return 2 * size(args) + 1024


def answer_limit(args):
    """The numbers an answer to a case on ``args`` may hold: every check's answer is at most as
    large as its input (a policy's actions, a gradient, probabilities), or small (a training run)."""
    return 4 * size(args) + 256


def _integer(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


class Conversation:
    """The grader's half of one worker's conversation (see the module docstring)."""

    def __init__(self, process, todo, pool):
        self.process, self.pool, self.server = process, pool, None
        self.allowed, self.refused = served.plan(todo) if todo else ({}, {})
        self.sent = self.calls = self.callbacks = self.episodes = 0
        self.marks, self.seeds, self.notes = [], set(), []
        self.case_probe, self.case_args, self.records = None, None, Records()
        self.limit = 0  # numbers a served call may carry in the current case (call_limit)
        self.envs = Environments()  # gym.make's environments of this run (served_env.py)

    # ---- the worker ------------------------------------------------------------------

    def send(self, message):
        self.sent += 1
        try:
            self.process.send(dict(message, n=self.sent))
        except OSError:  # the worker is gone (or its grading's sandbox); a message it left unread came out of turn
            answer = self.process.receive()
            raise Stop("violation" if isinstance(answer, dict) else "lost" if answer.startswith("lost:") else
                       "ended") from None
        except channel.ChannelTimeout as timeout:
            raise _stop(f"timeout:{timeout}") from None
        return self.sent

    def ask(self, message, expect):
        """Send ``message``; the worker's reply to it, serving its calls meanwhile."""
        number = self.send(message)
        while True:
            reply = self.process.receive()
            if isinstance(reply, str):
                raise _stop(reply)
            op = reply.get("op")
            if op == expect and _integer(reply.get("re")) and reply["re"] == number:
                return reply
            if op == "call" and _integer(reply.get("k")) and reply["k"] == self.calls + 1 \
                    and len(self.marks) < MAX_NESTING:
                self.calls += 1
                answer = self._serve(reply)
                self.send({"op": "reply", "re": reply["k"], **answer})
                continue
            raise Stop("violation")

    # ---- calls -------------------------------------------------------------------------

    def _serve(self, call):
        name = call.get("fn")
        if isinstance(name, str) and name in served_env.ENTRIES and "run_policy" in self.allowed:
            return self._env_call(name, call.get("args"))
        entry = self.allowed.get(name) if isinstance(name, str) else None
        if entry is None:
            why = self.refused.get(name) if isinstance(name, str) else None
            return _error("NotImplementedError", why or "the grader serves no such function")
        problem, marks = served.check_call(entry, call.get("args"), call.get("state"), self.limit)
        if problem:
            return _error("TypeError", problem)
        if self.calls > MAX_CALLS:
            return _error("RuntimeError", f"the grader answers at most {MAX_CALLS} calls per check")
        args, state = call["args"], call["state"]
        self.records.served.append(name)  # which functions the code asked for, in order (2.3.1's rule counts steps)
        self.marks.append(set(marks))
        try:
            if name == "eval_params" and self.case_probe in KNOWN_OBJECTIVE:
                return self._known(args)
            if name == "run_policy":
                return self._episode(args)
            if name == "eval_params" and self.episodes + int(args["num_rollouts"] if _integer(args["num_rollouts"])
                                                             else 0) > MAX_EPISODES:
                return _error("RuntimeError", f"the grader plays at most {MAX_EPISODES} episodes per check")
            reply = self._server_call(entry, args, state)
            if name == "eval_params" and reply["status"] == "ok":
                self._evaluation(args, reply)
            reply.pop("episodes", None)
            if reply["status"] == "ok" and size([reply["value"], reply["state"]]) > self.limit:
                return _error("RuntimeError", f"the answer of {entry.where} is larger than this check needs")
            return reply
        finally:
            self.marks.pop()

    def _episode(self, args):
        seed, seeded = args["seed"], args["seed"] is not None
        if self.episodes >= MAX_EPISODES:
            return _error("RuntimeError", f"the grader plays at most {MAX_EPISODES} episodes per check")
        env = None
        if args["env"] is not None:  # an environment of gym.make: its next episode when no seed is given
            env = self.envs.get(args["env"]) if _integer(args["env"]) else None
            if env is None:
                return _error("RuntimeError", "run_policy got an environment that is not open in this check")
        elif not seeded:
            seed = secrets.randbelow(2**31 - 1)
            while seed in self.seeds:
                seed = secrets.randbelow(2**31 - 1)
        reply = self._server_call(served.SERVED_BY_NAME["run_policy"], {"params": args["params"], "seed": seed,
                                                                          "env": args["env"]}, {})
        starts = (reply.pop("episodes", None) or {}).get("starts", ())
        if reply["status"] == "ok":
            self.episodes += 1
            if seed is not None:
                self.seeds.add(int(seed))
            determined = seeded if env is None else self.envs.played(env, seed)
            self.records.episodes.append(Episode(
                RUN_POLICY if env is None else IN_ENV, np.asarray(args["params"], dtype=np.float64).reshape(4),
                -1 if seed is None else int(seed), seeded, determined, float(reply["value"]),
                start_of(starts[0] if len(starts) else None), env=-1 if env is None else env.key))
        return reply

    def _env_call(self, name, args):
        """A call of a ``gym.make`` environment (``served_env.py``): checked, answered by the server's
        environment of the same key, and recorded (resets and steps of own loops)."""
        problem = served_env.check(name, args)
        if problem:
            return _error("TypeError" if name != "env_reset" else "ValueError", problem)
        if name == "env_make":
            made = self.envs.make()
            if made is None:
                return _error("RuntimeError", "the grader makes at most 2000 environments per check")
            key, evicted = made
            if evicted is not None:
                self._server_call(served_env.ENTRIES["env_close"], {"env": evicted}, {})
            reply = self._server_call(served_env.ENTRIES["env_make"], {"env": key, "id": args["id"]}, {})
            return dict(reply, value=key) if reply["status"] == "ok" else reply
        env = self.envs.get(args["env"])
        if name == "env_close":
            if env is not None:
                self.envs.close(env.key)
                self._server_call(served_env.ENTRIES["env_close"], {"env": env.key}, {})
            return {"status": "ok", "value": None, "state": {}}
        if env is None:
            return _error("RuntimeError", "this environment is not open in this check (closed, or made in another)")
        if name == "env_reset" and self.episodes >= MAX_EPISODES:
            return _error("RuntimeError", f"the grader plays at most {MAX_EPISODES} episodes per check")
        if name == "env_step" and self.envs.steps >= MAX_STEPS:
            return _error("RuntimeError", f"the grader plays at most {MAX_STEPS} steps per check")
        reply = self._server_call(served_env.ENTRIES[name], args, {})
        reply.pop("episodes", None)
        if reply["status"] != "ok":
            return reply
        try:
            if name == "env_reset":
                self.episodes += 1
                self.records.episodes.append(self.envs.reset(env, args["seed"], reply["value"]))
            else:
                self.envs.step(env, args["action"], reply["value"])
        except (TypeError, ValueError):
            return _error("RuntimeError", "the grader's environment could not answer this call")
        return reply

    def _evaluation(self, args, reply):
        episodes = reply.pop("episodes", None) or {}
        for params, seed, reward, start in zip(episodes.get("params", ()), episodes.get("seeds", ()),
                                               episodes.get("rewards", ()), episodes.get("starts", ())):
            self.episodes += 1
            self.records.episodes.append(Episode(EVALUATION, np.asarray(params, dtype=np.float64), int(seed),
                                                 seed >= 0, seed >= 0, float(reward), start_of(start)))
        self.records.evaluations.append((np.asarray(args["params"], dtype=np.float64).reshape(4),
                                         int(args["num_rollouts"]), int(args["seed"]), float(reply["value"])))

    def _known(self, args):
        """eval_params answered with the case's known objective, after the kit's own door checks."""
        try:
            params = np.asarray(args["params"], dtype=np.float64)
        except (TypeError, ValueError):
            return _error("TypeError", "params must be an array of numbers")
        if params.shape != (4,) or not np.all(np.isfinite(params)):
            return _error("ValueError", f"params must have shape (4,), one weight per observation component, got "
                                        f"shape {params.shape}" if params.shape != (4,) else
                          "params must hold only finite numbers")
        rollouts, seed = args["num_rollouts"], args["seed"]
        if not _integer(rollouts) or rollouts < 1:
            return _error("ValueError", "num_rollouts must be a positive integer")
        if not _integer(seed) or seed < 0:
            return _error("ValueError", "seed must be a non-negative integer")
        value = probes.training_objective(self.case_args["objective"])(params)
        self.records.evaluations.append((params, int(rollouts), int(seed), value))
        return {"status": "ok", "value": value, "state": {}}

    def _server_call(self, entry, args, state):
        if self.pool is None:
            return _error("NotImplementedError", f"{entry.where} is not available here")
        if self.server is None:
            try:
                self.server = self.pool.acquire()
            except ServerFailed:
                self.notes.append("the reference server could not start; calls of your code to other TODOs' "
                                  "functions failed (grade again)")
                return _error("RuntimeError", "the grader's reference could not answer this call")
        server, finished = self.server, False
        try:
            number = server.send({"op": "call", "fn": entry.name, "args": args, "state": state}, self.process.deadline)
            while True:
                message = server.receive(self.process.deadline)
                if message.get("op") == "done" and message.get("re") == number:
                    finished = True
                    break
                if message.get("op") != "callback":
                    raise ServerFailed("out of turn")
                server.send({"op": "callback-result", "re": message.get("k"), **self._callback(message)},
                            self.process.deadline)
        except ServerTimeout:
            raise Stop("timeout") from None
        except ServerFailed:
            self.notes.append("the reference server stopped while answering a call of your code; the call failed "
                              "(grade again)")
            return _error("RuntimeError", "the grader's reference could not answer this call")
        finally:
            if not finished:
                self.pool.release(server, broken=True)
                self.server = None
        if message.get("status") == "ok":
            reply = {"status": "ok", "value": message.get("value"), "state": message.get("state") or {}}
            if "episodes" in message:
                reply["episodes"] = message["episodes"]
            return reply
        return {"status": "error", "type": channel.text(message.get("type", "")),
                "message": channel.text(message.get("message", "")), "from_callback": bool(message.get("from_callback"))}

    def _callback(self, message):
        cb = message.get("cb")
        if not _integer(cb) or cb not in self.marks[-1] or self.callbacks >= MAX_CALLBACKS:
            return {"status": "error"}
        self.callbacks += 1
        back = self.ask({"op": "callback", "cb": int(cb), "args": message.get("args")}, "return")
        if back.get("status") == "ok" and served.check_value(back.get("value"), 10_000):
            return {"status": "ok", "value": back["value"]}
        return {"status": "error"}

    def release(self, broken=False):
        if self.server is not None:
            self.pool.release(self.server, broken)
            self.server = None


def accept(reply, probe, hidden, limit=None):
    """A worker's ``result`` as the judges see it: checked against the probe's schema and, with
    ``limit``, its size (``answer_limit``) before anything is kept; text only for visible cases
    (one line each, cut)."""
    status = reply.get("status")
    values = reply.get("values")
    schema = probes.RESULTS.get(probe, {})
    result = {"status": "error", "error": "", "warnings": [], "values": {}}
    if status == "ok":
        if not isinstance(values, dict) or set(values) != set(schema) or not all(
                isinstance(values[name], np.ndarray) and values[name].dtype.kind in kinds and values[name].ndim in ndims
                for name, (kinds, ndims) in schema.items()):
            result["error"] = "the answer does not have the values this check reads (their names, types and shapes)"
            return result
        if limit is not None and size(values) > limit:
            result["error"] = "the answer holds far more numbers than this check's input (more than it reads)"
            return result
        result.update(status="ok", values=dict(values))
    elif not hidden:
        result["error"] = channel.text(reply.get("error", "")) or "an error"
    if not hidden and isinstance(reply.get("warnings"), list):
        result["warnings"] = [channel.text(item) for item in reply["warnings"][:3] if isinstance(item, str)]
    return result


def _ended(code, phase):
    """Why the worker ended, in fixed words: once hidden inputs were sent, not even the signal."""
    if phase == "hidden":
        return STOPS["ended"] + " (during the hidden checks)"
    if code is not None and code > 128 and code - 128 in _SIGNALS:  # bubblewrap passes a signal on as 128 + it
        code = 128 - code
    if code is not None and code < 0:
        return f"the worker was ended: {_SIGNALS.get(-code, 'a signal')}"
    return "the worker ended before answering (sys.exit or os._exit in the code?)"


def run_cases(process, todo, visible, hidden, pool):
    """Run ``visible`` then ``hidden`` cases ([(case id, probe, args)]) on the started worker
    ``process`` for TODO ``todo``; (Outcome, {case id: result}). ``pool``: the ReferencePool that
    answers served calls (None: none are answered)."""
    conversation, outcome, results, timeout = Conversation(process, todo, pool), Outcome(), {}, ""
    shown = None  # how many of the conversation's notes came before its first hidden input (None: all)
    if hidden and not visible:  # a run of hidden cases alone: from its setup on, nothing of it is shown
        outcome.phase, shown = "hidden", 0
    try:
        conversation.ask({"op": "setup", "mode": "worker", "todo": todo}, "ready")
        for phase, cases in (("visible", visible), ("hidden", hidden)):
            if not cases and phase == "visible" and hidden:
                continue
            outcome.phase = phase
            if phase == "hidden" and cases and shown is None:
                shown = len(conversation.notes)
            for case_id, probe, args in cases:
                conversation.case_probe, conversation.case_args, conversation.records = probe, args, Records()
                conversation.limit = call_limit(args)
                reply = conversation.ask({"op": "case", "id": case_id, "probe": probe, "args": args}, "result")
                results[case_id] = accept(reply, probe, phase == "hidden", answer_limit(args))
                results[case_id]["records"] = conversation.records.arrays()
        outcome.phase = "done"
        try:
            conversation.send({"op": "exit"})
        except Stop:
            pass
    except Stop as stop:
        outcome.status, timeout = stop.status, stop.detail
        outcome.budget = stop.detail == TIMEOUTS["the submission's time budget"]
    finally:
        conversation.release(broken=outcome.status != "ok")
        # killed at once even when it answered everything: the next run begins only when every process
        # of this one is gone, and an interpreter's own exit takes longer than a kill
        outcome.exit_code, outcome.stderr_tail, outcome.seconds = process.finish(graceful=False)
        outcome.notes = list(dict.fromkeys(conversation.notes))
        outcome.visible_notes = list(dict.fromkeys(conversation.notes[:shown]))
    if outcome.status == "ended":
        outcome.detail = _ended(outcome.exit_code, outcome.phase)
    elif outcome.status == "timeout" and timeout and outcome.phase != "hidden":  # which limit, in fixed words
        outcome.detail = timeout
    elif outcome.status != "ok":
        outcome.detail = STOPS[outcome.status]
    return outcome, results


def missing(outcome, reason=None):
    """The result of a case that got no answer."""
    why = reason or (f"not answered: {outcome.detail}" if outcome is not None and outcome.status != "ok" else
                     "not answered" if outcome is not None else "not run")
    return {"status": "error", "error": why, "warnings": [], "values": {}, "records": Records().arrays()}
