"""The grader's worker: the only part of grading that runs the homework's code.

It runs in a separate process, inside the sandbox where one is available (``sandbox.py``), with
the kit under test on its ``sys.path``. It reads requests from its standard input and answers on
its standard output, each message an npz archive (``allow_pickle=False`` on both sides) behind an
8-byte length: a request is a list of cases, each naming a *probe* (a function below) and its
arguments; the answer gives, per case, the probe's values as numbers, or the error it raised,
and the warnings it gave. The worker decides nothing: the grader's trusted process compares the
values with the reference's. Whatever the student's code does here (patch pytest, ``sys.exit``,
write files, return objects that equal everything) can only change the numbers this process
sends back, and those are checked elsewhere.

Standalone on purpose: standard library and numpy, and ``hwlib`` from the kit under test, imported
by the probes. The grader's trusted process imports this module only for ``encode``/``decode``,
``read_message``/``write_message`` and the pure functions of the known objectives.
"""

from __future__ import annotations

import io
import json
import os
import struct
import sys
import time
import warnings

import numpy as np

MAX_MESSAGE_BYTES = 64 * 1024 * 1024
MAX_TEXT = 300  # characters kept of an error message or a warning
MAX_RECORDS = 10_000  # calls recorded by a spy


# --------------------------------------------------------------------------------------------
# Messages: npz archives, no pickle
# --------------------------------------------------------------------------------------------


def encode(value, arrays):
    """``value`` as JSON-able data; numpy arrays and scalars go into ``arrays`` as npz entries."""
    if isinstance(value, dict):
        return {str(key): encode(item, arrays) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [encode(item, arrays) for item in value]
    if isinstance(value, (np.ndarray, np.generic)):
        array = np.asarray(value)
        if array.dtype.kind not in "biuf":
            raise TypeError(f"only numeric arrays cross between grader and worker, got dtype {array.dtype}")
        name = f"a{len(arrays)}"
        arrays[name] = array
        return {"__array__": name}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot send a {type(value).__name__}")


def decode(value, arrays):
    if isinstance(value, dict):
        if set(value) == {"__array__"}:
            return arrays[value["__array__"]]
        return {key: decode(item, arrays) for key, item in value.items()}
    if isinstance(value, list):
        return [decode(item, arrays) for item in value]
    return value


def pack(message):
    arrays = {}
    meta = encode(message, arrays)
    buffer = io.BytesIO()
    np.savez(buffer, __json__=np.array(json.dumps(meta)), **arrays)
    return buffer.getvalue()


def unpack(data):
    with np.load(io.BytesIO(data), allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    meta = json.loads(str(arrays.pop("__json__")))
    return decode(meta, arrays)


def fingerprint(message):
    """A digest of ``message`` that depends only on its content (npz archives carry timestamps)."""
    import hashlib  # noqa: PLC0415

    arrays = {}
    meta = encode(message, arrays)
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True).encode())
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def write_message(fd, message):
    data = pack(message)
    view = memoryview(struct.pack(">Q", len(data)) + data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def read_exactly(fd, count):
    chunks, remaining = [], count
    while remaining:
        chunk = os.read(fd, min(remaining, 1 << 20))
        if not chunk:
            raise EOFError("the other side closed the channel")
        chunks.append(chunk)
        remaining -= len(chunk)
    return b"".join(chunks)


def read_message(fd):
    (length,) = struct.unpack(">Q", read_exactly(fd, 8))
    if length > MAX_MESSAGE_BYTES:
        raise ValueError(f"message of {length} bytes, more than {MAX_MESSAGE_BYTES}")
    return unpack(read_exactly(fd, length))


# --------------------------------------------------------------------------------------------
# Known objectives (the trusted side computes the same functions)
# --------------------------------------------------------------------------------------------


def known_function(spec):
    """The scalar function f of a finite-difference case: ``spec`` names its kind and coefficients.

    cubic:   f(v) = sum_i a_i v_i^3 + c                      (coordinates separate)
    coupled: f(v) = sum_i a_i v_i^3 + sin(b . v) + v^T M v   (coordinates interact)
    """
    kind = spec["kind"]
    a = np.asarray(spec["a"], dtype=np.float64)
    if kind == "cubic":
        c = float(spec.get("c", 0.0))

        def f(v):
            v = np.asarray(v, dtype=np.float64)
            return float(np.sum(a * v**3) + c)
    elif kind == "coupled":
        b = np.asarray(spec["b"], dtype=np.float64)
        m = np.asarray(spec["m"], dtype=np.float64)

        def f(v):
            v = np.atleast_1d(np.asarray(v, dtype=np.float64))
            return float(np.sum(a * v**3) + np.sin(b @ v) + v @ m @ v)
    else:
        raise ValueError(f"unknown test function kind {kind!r}")
    return f


def quadratic_objective(spec):
    """g(theta) = c - (theta - m)^T A (theta - m): a smooth stand-in for the expected reward, whose
    central differences are exact (up to rounding), so every step of eq. (4) is known."""
    a = np.asarray(spec["A"], dtype=np.float64)
    m = np.asarray(spec["m"], dtype=np.float64)
    c = float(spec["c"])

    def g(theta):
        d = np.asarray(theta, dtype=np.float64).reshape(-1) - m
        return float(c - d @ a @ d)

    return g


# --------------------------------------------------------------------------------------------
# Turning what the student's code returned into numbers
# --------------------------------------------------------------------------------------------

_PLAIN = (np.ndarray, np.generic, int, float, bool, list, tuple)


def numbers(value, what):
    """``value`` as a plain float64 array, or a TypeError saying what came back instead."""
    if not isinstance(value, _PLAIN) or (isinstance(value, np.ndarray) and type(value) is not np.ndarray):
        raise TypeError(f"{what} returned a {type(value).__module__}.{type(value).__name__}, not numbers")
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{what} returned something that is not an array of numbers ({error})") from None
    return array


def action(value):
    """An action as ``env.step`` takes it: a Python int (bools included), a numpy integer, or a
    0-d integer array, equal to 0 or 1."""
    if type(value) is np.ndarray and value.shape == () and value.dtype.kind in "iu":
        value = value.item()
    if type(value) not in (int, bool) and not isinstance(value, np.integer):
        raise TypeError(f"the policy returned a {type(value).__module__}.{type(value).__name__}; "
                        "env.step takes the int 0 or 1")
    number = int(value)
    if number not in (0, 1):
        raise ValueError(f"the policy returned {number}; actions are 0 (left) and 1 (right)")
    return number


# --------------------------------------------------------------------------------------------
# Probes: each calls the homework's functions on one case's arguments
# --------------------------------------------------------------------------------------------


class _Patches:
    """Replacements of module attributes for one probe, undone when it ends."""

    def __init__(self):
        self._undo = []

    def set(self, module, name, value):
        self._undo.append((module, name, getattr(module, name)))
        setattr(module, name, value)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for module, name, value in reversed(self._undo):
            setattr(module, name, value)


def _import(name):
    import importlib  # noqa: PLC0415

    module = importlib.import_module(name)
    kit = os.path.realpath(KIT_DIR)
    if not os.path.realpath(getattr(module, "__file__", "") or "").startswith(kit + os.sep):
        raise ImportError(f"{name} was not imported from the kit under test")
    return module


def probe_policy_actions(args):
    cartpole = _import("hwlib.cartpole")
    params, observations = np.asarray(args["params"]), np.asarray(args["obs"])
    actions = [action(cartpole.CartPoleLinearPolicy(p.copy())(o.copy())) for p, o in zip(params, observations)]
    return {"actions": np.array(actions, dtype=np.int64)}


def probe_finite_diff(args):
    finite_diff = _import("hwlib.finite_diff")
    f = known_function(args["f"])
    x = float(args["x"]) if args.get("x_scalar") else np.array(args["x"], dtype=np.float64)
    h = float(args["h"]) if args.get("h_scalar") else np.array(args["h"], dtype=np.float64)
    calls = [0]

    def counted(v):
        calls[0] += 1
        return f(v)

    gradient = numbers(finite_diff.scalar_finite_diff(counted, x, h), "scalar_finite_diff")
    return {"gradient": gradient, "calls": np.int64(calls[0])}


def _spy_run_policy(records, patches):
    cartpole = _import("hwlib.cartpole")
    policy_search = _import("hwlib.policy_search")
    real = cartpole.run_policy
    draw = np.random.default_rng(int.from_bytes(os.urandom(8), "little"))

    def spy(policy, seed=None, env=None):
        params = getattr(policy, "params", None)
        try:
            params = np.array(params, dtype=np.float64).reshape(4)
        except (TypeError, ValueError):
            params = np.full(4, np.nan)
        seeded = seed is not None
        used = seed if seeded else int(draw.integers(0, 2**31 - 1))  # an unseeded episode: a random start
        reward = real(policy, seed=used, env=env)
        if len(records) < MAX_RECORDS:
            records.append((params, used, seeded, float(reward)))
        return reward

    for module in (cartpole, policy_search, sys.modules.get("hwlib")):
        if module is not None and hasattr(module, "run_policy"):
            patches.set(module, "run_policy", spy)


def probe_eval_params(args):
    policy_search = _import("hwlib.policy_search")
    records = []
    params = np.array(args["params"], dtype=np.float64)
    with _Patches() as patches:
        _spy_run_policy(records, patches)
        first = numbers(policy_search.eval_params(params.copy(), int(args["num_rollouts"]), seed=int(args["seed"])),
                        "eval_params")
        played_first = len(records)
        again = numbers(policy_search.eval_params(params.copy(), int(args["num_rollouts"]), seed=int(args["seed"])),
                        "eval_params")
    table = records[:played_first]
    return {
        "value": first, "value_again": again, "episodes": np.int64(played_first),
        "episode_params": np.array([r[0] for r in table]).reshape(-1, 4),
        "episode_seeds": np.array([r[1] for r in table], dtype=np.int64),
        "episode_seeded": np.array([r[2] for r in table], dtype=bool),
        "episode_rewards": np.array([r[3] for r in table], dtype=np.float64),
        "seeds_again": np.array([r[1] for r in records[played_first:]], dtype=np.int64),
    }


def _training_values(run):
    rewards = numbers(getattr(run, "rewards", None), "train_cartpole_policy's rewards")
    history = numbers(getattr(run, "params_history", None), "train_cartpole_policy's params_history")
    final = numbers(getattr(getattr(run, "policy", None), "params", None), "the trained policy's params")
    return {"rewards": rewards, "params_history": history, "final_params": final}


def _train(policy_search, args):
    return policy_search.train_cartpole_policy(
        num_training_iterations=int(args["iterations"]), num_rollouts_per_eval=int(args["rollouts"]),
        learning_rate=float(args["learning_rate"]), fd_step=float(args["fd_step"]), seed=int(args["seed"]),
        initial_params=np.array(args["initial_params"], dtype=np.float64))


def probe_train_known(args):
    policy_search = _import("hwlib.policy_search")
    g = quadratic_objective(args["objective"])
    calls = [0]

    def known_eval_params(params, num_rollouts=None, seed=None):
        calls[0] += 1
        return g(params)

    with _Patches() as patches:
        patches.set(policy_search, "eval_params", known_eval_params)
        run = _train(policy_search, args)
    values = _training_values(run)
    values["evaluations"] = np.int64(calls[0])
    return values


def probe_train_real(args):
    import inspect  # noqa: PLC0415

    policy_search = _import("hwlib.policy_search")
    real = policy_search.eval_params
    signature = inspect.signature(real)
    calls = []

    def recorded_eval_params(*call_args, **call_kwargs):
        value = real(*call_args, **call_kwargs)
        bound = signature.bind(*call_args, **call_kwargs)
        bound.apply_defaults()
        if len(calls) < MAX_RECORDS:
            calls.append((np.array(bound.arguments["params"], dtype=np.float64).reshape(4),
                          int(bound.arguments["num_rollouts"]), int(bound.arguments["seed"]), float(value)))
        return value

    with _Patches() as patches:
        patches.set(policy_search, "eval_params", recorded_eval_params)
        run = _train(policy_search, args)
    values = _training_values(run)
    values.update({
        "call_params": np.array([c[0] for c in calls]).reshape(-1, 4),
        "call_rollouts": np.array([c[1] for c in calls], dtype=np.int64),
        "call_seeds": np.array([c[2] for c in calls], dtype=np.int64),
        "call_values": np.array([c[3] for c in calls], dtype=np.float64),
    })
    return values


def probe_settings_value(args):
    settings = _import("hwlib.settings")
    name = args["name"]
    value = getattr(settings, name, None)
    if value is None:
        raise ValueError(f"{name} is None: it is not set yet")
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} is a {type(value).__name__}, not a number")
    return {"value": np.float64(value)}


def probe_sigmoid(args):
    logreg = _import("hwlib.logreg")
    z = np.array(args["z"], dtype=np.float64)
    return {"values": numbers(logreg.sigmoid(z.copy()), "sigmoid")}


def probe_predict_prob(args):
    logreg = _import("hwlib.logreg")
    classifier = logreg.TwoClassLogisticRegressionClassifier(int(args["n_features"]))
    classifier.weights = np.array(args["weights"], dtype=np.float64)
    return {"probabilities": numbers(classifier.predict_prob(np.array(args["X"], dtype=np.float64)), "predict_prob")}


def probe_gradient_step(args):
    logreg = _import("hwlib.logreg")
    classifier = logreg.TwoClassLogisticRegressionClassifier(int(args["n_features"]))
    classifier.weights = np.array(args["weights"], dtype=np.float64)
    X, y = np.array(args["X"], dtype=np.float64), np.array(args["y"])
    after = []
    for _ in range(int(args["steps"])):
        classifier.gradient_ascent_step(X.copy(), y.copy(), float(args["learning_rate"]))
        after.append(numbers(classifier.weights, "self.weights after gradient_ascent_step").copy())
    return {"weights": np.array(after)}


def probe_one_vs_rest(args):
    logreg = _import("hwlib.logreg")
    model = logreg.MultiClassLogisticRegressionClassifier(int(args["n_features"]), int(args["n_classes"]))
    for c, start in enumerate(np.array(args.get("initial_weights", ()), dtype=np.float64)):  # where fit starts
        model.classifiers[c].weights = start.copy()
    accuracies = model.fit(np.array(args["X"], dtype=np.float64), np.array(args["y"]),
                           float(args["learning_rate"]), int(args["n_iters"]))
    weights = np.array([numbers(c.weights, "classifiers[c].weights") for c in model.classifiers])
    return {"weights": weights, "accuracies": numbers(accuracies, "fit")}


def probe_ll_gradient(args):
    logreg = _import("hwlib.logreg")
    gradient = logreg.log_likelihood_gradient(np.array(args["weights"], dtype=np.float64),
                                              np.array(args["X"], dtype=np.float64), np.array(args["y"]))
    return {"gradient": numbers(gradient, "log_likelihood_gradient")}


def _action_kind(value):
    """0: a type ``env.step`` takes (gymnasium's own test: an int, bools included, a numpy integer,
    a 0-d integer array); else what it is: 1 a numpy bool, 2 a float, 3 an array, 4 anything else."""
    import gymnasium  # noqa: PLC0415 - the kit's own dependency, there in the sandbox

    if gymnasium.spaces.Discrete(2).contains(value):
        return 0
    if isinstance(value, np.bool_):
        return 1
    if isinstance(value, (float, np.floating)):
        return 2
    return 3 if isinstance(value, np.ndarray) else 4


def probe_policy_choices(args):
    """The policy's action on each (params, obs) row as a number (whatever numeric type it came
    in), and whether env.step takes it as it is (``accepted``, with its ``kinds``)."""
    cartpole = _import("hwlib.cartpole")
    params, observations = np.asarray(args["params"]), np.asarray(args["obs"])
    actions, kinds = [], []
    for p, o in zip(params, observations):
        value = cartpole.CartPoleLinearPolicy(p.copy())(o.copy())
        if not isinstance(value, _PLAIN) or np.asarray(value).dtype.kind not in "biuf" or np.asarray(value).size != 1:
            raise TypeError(f"the policy returned {type(value).__module__}.{type(value).__name__}, not the number 0 or 1")
        kinds.append(_action_kind(value))
        actions.append(float(np.asarray(value, dtype=np.float64).reshape(())))
    return {"actions": np.array(actions, dtype=np.float64), "accepted": np.array(kinds) == 0,
            "kinds": np.array(kinds, dtype=np.int64)}


# Services: run on the reference kit only, to re-score what a student's run produced.


def probe_episode_rewards(args):
    cartpole = _import("hwlib.cartpole")
    params, seeds = np.array(args["params"], dtype=np.float64).reshape(-1, 4), np.array(args["seeds"], dtype=np.int64)
    rewards = [cartpole.run_policy(cartpole.CartPoleLinearPolicy(p), seed=int(s)) for p, s in zip(params, seeds)]
    return {"rewards": np.array(rewards, dtype=np.float64)}


def probe_eval_many(args):
    policy_search = _import("hwlib.policy_search")
    params = np.array(args["params"], dtype=np.float64).reshape(-1, 4)
    values = [policy_search.eval_params(p, int(r), seed=int(s))
              for p, r, s in zip(params, np.asarray(args["rollouts"]), np.asarray(args["seeds"]))]
    return {"values": np.array(values, dtype=np.float64)}


def probe_train_notebook(args):
    policy_search = _import("hwlib.policy_search")
    settings = _import("hwlib.settings")
    cartpole = _import("hwlib.cartpole")
    run = policy_search.train_cartpole_policy(learning_rate=float(args["learning_rate"]))
    return {"rewards": np.array(run.rewards, dtype=np.float64),
            "deadline": np.int64(settings.CONVERGENCE_DEADLINE),
            "max_reward": np.float64(cartpole.MAX_EPISODE_REWARD),
            "iterations": np.int64(settings.NUM_TRAINING_ITERATIONS),
            "seed": np.int64(settings.TRAINING_SEED)}


PROBES = {name[len("probe_"):]: function for name, function in globals().items() if name.startswith("probe_")}


# --------------------------------------------------------------------------------------------
# The loop
# --------------------------------------------------------------------------------------------

KIT_DIR = "/kit"
MAIN_PID = os.getpid()


def _text(text):
    text = " ".join(str(text).split())
    return text if len(text) <= MAX_TEXT else text[:MAX_TEXT - 3] + "..."


def run_case(case):
    started = time.perf_counter()
    result = {"id": case["id"], "status": "ok", "error": "", "warnings": [], "values": {}}
    defaults = np.seterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            values = PROBES[case["probe"]](case["args"])
            for name, value in values.items():
                array = np.asarray(value)
                if array.dtype.kind not in "biuf":
                    raise TypeError(f"{name}: not numbers")
                result["values"][name] = array
        except BaseException as error:  # noqa: BLE001 - SystemExit and KeyboardInterrupt too: the student's code raised them
            result["status"] = "error"
            result["error"] = _text(f"{type(error).__name__}: {error}")
            result["values"] = {}
        finally:
            np.seterr(**defaults)
    if os.getpid() != MAIN_PID:  # a fork of the student's code came back here: it must not answer
        os._exit(0)
    seen = []
    for warning in caught:
        text = _text(f"{warning.category.__name__}: {warning.message}")
        if text not in seen:
            seen.append(text)
    result["warnings"] = seen[:3]
    result["seconds"] = round(time.perf_counter() - started, 4)
    return result


def _set_limits(cpu_seconds, memory_bytes):
    import resource  # noqa: PLC0415

    for limit, value in ((resource.RLIMIT_CPU, cpu_seconds), (resource.RLIMIT_AS, memory_bytes)):
        if value:
            soft, hard = resource.getrlimit(limit)
            value = value if hard == resource.RLIM_INFINITY else min(value, hard)
            resource.setrlimit(limit, (value, value))


def main(argv):
    global KIT_DIR  # noqa: PLW0603
    KIT_DIR = argv[1]
    cpu = int(argv[2]) if len(argv) > 2 else 0
    memory = int(argv[3]) if len(argv) > 3 else 0
    _set_limits(cpu, memory)
    requests, answers = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(2, 1)  # the student's prints go to the error stream, never into the answers
    sys.stdout = sys.stderr
    script_dir = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [KIT_DIR] + [entry for entry in sys.path if entry and os.path.abspath(entry) != script_dir]
    sys.dont_write_bytecode = True
    while True:
        try:
            request = read_message(requests)
        except EOFError:
            return 0
        if request.get("op") == "exit":
            return 0
        results = [run_case(case) for case in request["cases"]]
        write_message(answers, {"results": results})


if __name__ == "__main__":
    sys.exit(main(sys.argv))
