"""The sandboxed side of grading: one process's loop, as the student's worker or as the reference server.

``worker.py`` starts this module from the kit the process runs (the grader copies this folder there as
``_hwgrade/``). The grader speaks first,
and every message it sends carries its number ``n``:

* ``setup`` {todo, mode}: answered ``ready``. A *worker* (mode "worker") then replaces every
  function of ``served.plan(todo)`` by a proxy that forwards its calls, and every refused one by
  a stub that says why (and where ``run_policy`` is served, ``gym.make`` of CartPole gives an
  environment the grader answers: ``served_env.py``); a *server* (mode "server", the reference
  kit only) records the episodes its ``eval_params`` and ``run_policy`` play, with their start
  states, and holds the environments of those ``gym.make`` calls.
* ``case`` {id, probe, args}: the worker runs the probe and answers ``result`` {re: n, status,
  error, warnings, values}.
* while a proxy waits for its ``reply`` {re: k} to its ``call`` {k, fn, args, state} (k: the
  worker's own count of calls), the grader may ask ``callback`` {cb, args}: the worker calls the
  function it passed as argument ``cb`` and answers ``return`` {re: n, status, value}.
* a server answers ``call`` and ``probe`` {probe, args} with ``done`` {re: n, ...}; while it runs
  a call it may ask ``callback`` {k, cb, args} and wait for ``callback-result`` {re: k}, serving
  nested ``call``\\s meanwhile.

Nothing here is trusted by the grader: it checks every message against what it asked
(``broker.py``). Standard library, numpy and the kit under test.
"""

from __future__ import annotations

import builtins
import inspect
import os
import sys
import time
import traceback
import warnings

import numpy as np

from . import channel, probes, served, served_env

_IO = {"in": None, "out": None, "k": 0, "mode": None, "env_class": None, "import_error": ""}
MAIN_PID = os.getpid()
_CALLBACKS = []  # the functions passed to pending proxy calls, by id
_LAST_CALLBACK_ERROR = [None]
_EPISODES = []  # server: a stack of episode lists, one per call being answered
_ERRORS = {name: getattr(builtins, name) for name in (
    "ValueError", "TypeError", "ZeroDivisionError", "FloatingPointError", "OverflowError", "ArithmeticError",
    "IndexError", "KeyError", "AttributeError", "NotImplementedError", "RuntimeError", "MemoryError")}


def _send(message):
    channel.write_message(_IO["out"], message)


def _receive():
    try:
        return channel.read_message(_IO["in"])
    except EOFError:
        os._exit(0)


def _broken():
    os._exit(70)  # the grader never sends what this process cannot answer: stop, it notices


# --------------------------------------------------------------------------------------------
# The worker: cases, and the proxies of other TODOs' functions
# --------------------------------------------------------------------------------------------


def run_case(message):
    started = time.perf_counter()
    result = {"op": "result", "re": message.get("n"), "status": "ok", "error": "", "warnings": [], "values": {}}
    if _IO["import_error"]:  # the kit raised while it was imported: each case says so, and nothing of it runs
        return dict(result, status="error", error=_IO["import_error"], seconds=0.0)
    defaults = np.seterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            values = probes.PROBES[message["probe"]](message["args"])
            for name, value in values.items():
                array = np.asarray(value)
                if array.dtype.kind not in "biuf":
                    raise TypeError(f"{name}: not numbers")
                result["values"][name] = array
        except BaseException as error:  # noqa: BLE001 - SystemExit and KeyboardInterrupt too: the student's code raised them
            result.update(status="error", error=channel.text(f"{type(error).__name__}: {error}"), values={})
        finally:
            np.seterr(**defaults)
    if os.getpid() != MAIN_PID:  # a fork of the student's code came back here: it must not answer
        os._exit(0)
    seen = []
    for warning in caught:
        line = channel.text(f"{warning.category.__name__}: {warning.message}")
        if line not in seen:
            seen.append(line)
    result["warnings"] = seen[:3]
    result["seconds"] = round(time.perf_counter() - started, 4)
    return result


def _get(obj, name):
    if "." in name:
        items, attribute = name.split(".", 1)
        return [getattr(item, attribute) for item in getattr(obj, items)]
    return getattr(obj, name)


def _set(obj, name, value):
    if "." in name:
        items, attribute = name.split(".", 1)
        for item, part in zip(getattr(obj, items), value):
            setattr(item, attribute, part)
    else:
        setattr(obj, name, value)


def _exception(reply):
    if reply.get("from_callback") and _LAST_CALLBACK_ERROR[0] is not None:
        error, _LAST_CALLBACK_ERROR[0] = _LAST_CALLBACK_ERROR[0], None
        return error
    kind, message = str(reply.get("type", "")), str(reply.get("message", ""))
    if kind == "TodoNotDone":
        return getattr(sys.modules.get("hwlib.machinery.todos"), "TodoNotDone", NotImplementedError)(message)
    cls = _ERRORS.get(kind)
    return cls(message) if cls is not None else RuntimeError(f"{kind}: {message}")


def call(entry, args, state):
    """Have the grader answer ``entry`` (a ``served.Served``) on ``args``: (value, updated state)."""
    base = len(_CALLBACKS)
    for name in entry.callables:
        if callable(args.get(name)):
            _CALLBACKS.append(args[name])
            args[name] = {"__callable__": len(_CALLBACKS) - 1}
    _IO["k"] += 1
    number = _IO["k"]
    try:
        try:
            _send({"op": "call", "k": number, "fn": entry.name, "args": args, "state": state})
        except TypeError:
            raise TypeError(f"{entry.where} was called with something that is not numbers; in grading it "
                            "is answered on the grader's side, which takes numbers only") from None
        while True:
            message = _receive()
            op = message.get("op")
            if op == "reply" and message.get("re") == number:
                break
            if op == "callback":
                _answer_callback(message)
            elif op == "exit":
                os._exit(0)
            else:
                _broken()
    finally:
        del _CALLBACKS[base:]
    if message.get("status") == "ok":
        return message.get("value"), message.get("state") or {}
    raise _exception(message)


def _answer_callback(message):
    reply = {"op": "return", "re": message.get("n"), "status": "error"}
    cb = message.get("cb")
    if isinstance(cb, int) and 0 <= cb < len(_CALLBACKS):
        try:
            value = _CALLBACKS[cb](*message.get("args", []))
            channel.pack({"value": value})  # numbers only, or a TypeError here
            reply.update(status="ok", value=value)
        except BaseException as error:  # noqa: BLE001 - handed back to the student's code that raised it
            _LAST_CALLBACK_ERROR[0] = error if not isinstance(error, TypeError) or "cannot send" not in str(error) \
                else TypeError("the function passed to a served call returned something that is not numbers")
    _send(reply)


def _proxy(entry, original):
    signature = inspect.signature(original)

    def proxy(*call_args, **call_kwargs):
        bound = signature.bind(*call_args, **call_kwargs)
        bound.apply_defaults()
        arguments = dict(bound.arguments)
        owner = arguments.pop(next(iter(signature.parameters))) if entry.owner else None
        if entry.name == "run_policy":
            arguments = _episode(arguments)
        state = {name: _get(owner, name) for name in entry.init + entry.state} if owner is not None else {}
        value, updated = call(entry, arguments, state)
        for name in entry.updates:
            if name in updated:
                _set(owner, name, updated[name])
        return value

    for attribute in ("__name__", "__qualname__", "__doc__", "__module__"):
        setattr(proxy, attribute, getattr(original, attribute, None))
    proxy.__signature__ = signature
    return proxy


def _episode(arguments):
    """run_policy(policy, seed, env) as the grader plays it: the policy's parameters, the seed and
    the key of the environment (None, or one of ``gym.make``'s served environments)."""
    cartpole = sys.modules["hwlib.cartpole"]
    policy = arguments.get("policy")
    if type(policy) is not cartpole.CartPoleLinearPolicy:
        raise TypeError(f"in grading, run_policy plays CartPoleLinearPolicy(params) on the grader's side; got a "
                        f"{type(policy).__name__}")
    env = served_env.env_key(arguments.get("env"), _IO["env_class"])
    return {"params": policy.params, "seed": arguments.get("seed"), "env": env}


def _import_error(error):
    """The words of an error the kit's code raised while imported, with the kit's file and line it came from."""
    kit = os.path.realpath(probes.KIT_DIR) + os.sep
    frames = [frame for frame in traceback.extract_tb(error.__traceback__) if os.path.realpath(frame.filename).startswith(kit)]
    where = f" at {os.path.relpath(frames[-1].filename, kit)} line {frames[-1].lineno}" if frames else ""
    return channel.text(f"{type(error).__name__}: {error} ({probes.IMPORT_FAILED}{where})")


def _refusing(why, original):
    def stub(*args, **kwargs):
        raise NotImplementedError(why)

    for attribute in ("__name__", "__qualname__", "__doc__", "__module__"):
        setattr(stub, attribute, getattr(original, attribute, None))
    return stub


def _replace(entry, make):
    """Put ``make(original)`` wherever the kit holds ``entry``'s function (or method)."""
    try:
        module = probes._import(entry.module)
    except ImportError:
        return  # a kit without this module (1.3.3's holds settings.py only)
    if entry.owner:
        cls = getattr(module, entry.owner, None)
        if cls is not None and entry.attribute in vars(cls):
            setattr(cls, entry.attribute, make(vars(cls)[entry.attribute]))
        return
    original = getattr(module, entry.attribute, None)
    if original is None:
        return
    replacement = make(original)
    for name, loaded in list(sys.modules.items()):
        if name == "hwlib" or name.startswith("hwlib."):
            for key, value in list(vars(loaded).items()):
                if value is original:
                    setattr(loaded, key, replacement)


def _setup_worker(todo):
    try:
        probes._import("hwlib")
    except ImportError:
        pass
    except BaseException as error:  # noqa: BLE001 - a NameError, sys.exit, ... in the kit's code at import
        _IO["import_error"] = _import_error(error)
        return
    allowed, refused = served.plan(todo) if todo else ({}, {})
    for name, entry in allowed.items():
        _replace(entry, lambda original, entry=entry: _proxy(entry, original))
    for name, why in refused.items():
        _replace(served.SERVED_BY_NAME[name], lambda original, why=why: _refusing(why, original))
    if "run_policy" in allowed:  # every episode of this run is played on the trusted side, gym.make's too
        _IO["env_class"] = served_env.install(call)


# --------------------------------------------------------------------------------------------
# The reference server
# --------------------------------------------------------------------------------------------


class CallbackFailed(Exception):
    """The worker's function, called back, raised: the student's own exception goes up in the worker."""


def _callback(cb):
    def function(*args):
        _IO["k"] += 1
        number = _IO["k"]
        _send({"op": "callback", "k": number, "cb": cb, "args": list(args)})
        while True:
            message = _receive()
            if message.get("op") == "callback-result" and message.get("re") == number:
                break
            if message.get("op") == "call":
                _execute(message)
            elif message.get("op") == "exit":
                os._exit(0)
            else:
                _broken()
        if message.get("status") == "ok":
            return message.get("value")
        raise CallbackFailed()

    return function


def _recorder(real):
    def run_policy(policy, seed=None, env=None):
        if not _EPISODES:  # outside a served call (the notebook's training run): as the kit plays it
            return real(policy, seed=seed, env=env)
        recorder = served_env.StartRecorder(_ENVS[0].scratch() if env is None else env)
        reward = real(policy, seed=seed, env=recorder)
        _EPISODES[-1].append((np.array(policy.params, dtype=np.float64), -1 if seed is None else int(seed), reward,
                              recorder.start))
        return reward

    return run_policy


_ENVS = []  # server: the environments of served gym.make calls (served_env.Table)


def _setup_server():
    probes._import("hwlib")
    policy_search = probes._import("hwlib.policy_search")
    policy_search.run_policy = _recorder(policy_search.run_policy)
    from gymnasium.envs.registration import make  # noqa: PLC0415 - the kit's own dependency

    _ENVS.append(served_env.Table(make))


def _play_served_episode(module, args):
    """run_policy as a served call: in the environment of ``args["env"]`` (its next episode when
    the seed is None) or else in the scratch environment, always seeded there; recorded with its
    start state."""
    table = _ENVS[0]
    recorder = served_env.StartRecorder(table.scratch() if args.get("env") is None else table.get(args["env"]))
    policy = module.CartPoleLinearPolicy(args["params"])
    reward = module.run_policy(policy, seed=args["seed"], env=recorder)
    _EPISODES[-1].append((np.array(policy.params, dtype=np.float64), -1 if args["seed"] is None else int(args["seed"]),
                          reward, recorder.start))
    return reward


def _execute(message):
    reply = {"op": "done", "re": message.get("n"), "status": "ok", "value": None, "state": {}}
    _EPISODES.append([])
    try:
        if message["fn"] in served_env.ENTRIES:  # gym.make's environments (served_env.py)
            value = _ENVS[0].execute(message["fn"], message["args"])
        else:
            entry = served.SERVED_BY_NAME[message["fn"]]
            module = probes._import(entry.module)
            args = {name: _callback(value["__callable__"]) if served.is_callable_mark(value) else value
                    for name, value in message["args"].items()}
            state = message.get("state") or {}
            if entry.name == "run_policy":
                value = _play_served_episode(module, args)
            elif entry.owner:
                obj = getattr(module, entry.owner)(*[state[name] for name in entry.init])
                for name in entry.state:
                    _set(obj, name, state[name])
                value = getattr(obj, entry.attribute)(**args)
                reply["state"] = {name: _get(obj, name) for name in entry.updates}
            else:
                value = getattr(module, entry.attribute)(**args)
        channel.pack({"value": value, "state": reply["state"]})
        reply["value"] = value
    except CallbackFailed:
        reply.update(status="error", from_callback=True, type="", message="")
    except BaseException as error:  # noqa: BLE001 - the reference's own errors go back as the kit raises them
        reply.update(status="error", type=type(error).__name__, message=channel.text(error), value=None, state={})
    finally:
        episodes = _EPISODES.pop()
    reply["episodes"] = {"params": np.array([e[0] for e in episodes], dtype=np.float64).reshape(-1, 4),
                         "seeds": np.array([e[1] for e in episodes], dtype=np.int64),
                         "rewards": np.array([e[2] for e in episodes], dtype=np.float64),
                         "starts": np.array([e[3] for e in episodes], dtype=np.float64).reshape(-1, 4)}
    _send(reply)


# --------------------------------------------------------------------------------------------
# The loop
# --------------------------------------------------------------------------------------------


WARM = ("gymnasium",)  # installed packages the kit imports: loaded before the kit, while the run waits for its turn


def _warm():
    """Import the installed packages the kit needs (trusted code) before the first message: the
    grader may start this process while another run executes, and lets it begin (its first
    message, after which the kit's code is imported) only once that run has ended."""
    for name in WARM:
        try:
            __import__(name)
        except Exception:  # noqa: BLE001 - the kit's own import says what is missing
            pass


def main(kit_dir, requests, answers):
    global MAIN_PID
    MAIN_PID = os.getpid()  # a zygote imported this module before it forked this process
    probes.KIT_DIR = kit_dir
    _IO.update({"in": requests, "out": answers})
    _warm()
    while True:
        message = _receive()
        op = message.get("op")
        if op == "exit":
            return 0
        if op == "setup" and _IO["mode"] is None:
            _IO["mode"] = "server" if message.get("mode") == "server" else "worker"
            _setup_server() if _IO["mode"] == "server" else _setup_worker(message.get("todo"))
            _send({"op": "ready", "re": message.get("n")})
        elif op == "case" and _IO["mode"] == "worker":
            _send(run_case(message))
        elif op == "call" and _IO["mode"] == "server":
            _execute(message)
        elif op == "probe" and _IO["mode"] == "server":
            result = run_case({"n": message.get("n"), "probe": message.get("probe"), "args": message.get("args")})
            result["op"] = "done"
            _send(result)
        else:
            _broken()
