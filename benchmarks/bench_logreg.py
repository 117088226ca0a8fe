"""Problem 2 benchmark: the one-vs-rest fit as students write it, against scikit-learn.

Run from the kit's root, after ``pip install -r benchmarks/requirements-bench.txt``:

    python benchmarks/bench_logreg.py              # BLAS with its default number of threads
    python benchmarks/bench_logreg.py --threads 1  # single-threaded BLAS
    python benchmarks/bench_logreg.py --blas       # one fit with each number of BLAS threads, side by side

``--blas`` needs no scikit-learn: it times the kit's ``fit`` (the notebook's 2.3.2 training) in fresh
processes with ``OPENBLAS_NUM_THREADS`` 1 and the number of cores (OpenBLAS reads it once, when numpy
loads), in turns, and prints the load. ``hwlib`` caps BLAS at one thread unless the variable is set
(``hwlib/__init__.py``); this is the measurement behind that choice.

It uses the notebook's data (the course's ``data/data.npz`` if present, else the synthetic
stand-in), its split and its settings (``hwlib/settings.py``: learning rate, iterations), and
prints in one run the time of ``MultiClassLogisticRegressionClassifier.fit``

| line                          | the code in the TODO blocks                                                     |
|-------------------------------|---------------------------------------------------------------------------------|
| kit solution                  | the instructor's solutions: one matrix-vector step per class                   |
| natural ``<todo>_<style>``    | one solution of ``tests/grader/natural_solutions/`` in place of the kit's, the rest the kit's |
| scikit-learn, multinomial     | ``LogisticRegression()`` (lbfgs, L2, C=1), up to 1000 iterations               |
| scikit-learn, one-vs-rest     | ``OneVsRestClassifier(LogisticRegression())``, same settings                   |

with the test accuracy of each. A natural solution that would take longer than ``--budget``
seconds (the per-sample loops) is timed over one iteration (the better of two) and the time
multiplied by the number of iterations; the line says so. Exits with status 1 if a natural solution's
predictions differ from the kit's, or if the kit's test accuracy is more than 2 points below
scikit-learn's. Times on a shared machine are noisy: compare the lines of one run.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
import types
import warnings
from pathlib import Path


def parse_arguments():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=None, help="BLAS threads (default: the library's own choice)")
    parser.add_argument("--iterations", type=int, default=None, help="training iterations (default: settings.P2_NUM_ITERATIONS)")
    parser.add_argument("--budget", type=float, default=20.0, help="seconds a natural solution may take before it is extrapolated")
    parser.add_argument("--blas", action="store_true", help="only compare BLAS threads for one fit (no scikit-learn needed)")
    parser.add_argument("--rounds", type=int, default=3, help="with --blas: fits per number of threads")
    parser.add_argument("--styles", default="2.2.1_naive,2.2.3_matrix,2.2.3_per_sample_loop,2.3.1_loop,2.3.1_two_class_fit",
                        help="comma-separated natural solutions to time (file names without .py), or 'all'")
    return parser.parse_args()


ONE_FIT = """
import time
from hwlib import MultiClassLogisticRegressionClassifier, load_food_cutting, settings, train_test_split
data = load_food_cutting()
X, _, y, _ = train_test_split(data.features, data.labels, test_fraction=settings.TEST_FRACTION, seed=settings.SPLIT_SEED)
start = time.perf_counter()
MultiClassLogisticRegressionClassifier(X.shape[1], len(data.names)).fit(X, y, settings.P2_LEARNING_RATE, settings.P2_NUM_ITERATIONS)
print(time.perf_counter() - start)
"""


def compare_blas_threads(rounds):
    """One fit in a fresh process per number of BLAS threads, in turns, ``rounds`` times each."""
    import subprocess

    cores = os.cpu_count() or 1
    seconds = {1: [], cores: []}
    for _ in range(rounds):
        for threads in seconds:
            env = {**os.environ, "OPENBLAS_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
            done = subprocess.run([sys.executable, "-c", ONE_FIT], env=env, capture_output=True, text=True, check=True)
            seconds[threads].append(float(done.stdout.strip().splitlines()[-1]))
            print(f"  {threads} BLAS thread(s): {seconds[threads][-1]:.2f} s (load {os.getloadavg()[0]:.1f})", flush=True)
    for threads, times in seconds.items():
        print(f"one fit ({settings_line()}), {threads} BLAS thread(s): median {sorted(times)[len(times) // 2]:.2f} s, "
              f"min {min(times):.2f} s, max {max(times):.2f} s")
    return 0


def settings_line():
    from hwlib import settings  # noqa: PLC0415

    return f"{settings.P2_NUM_ITERATIONS} iterations x 7 classes"


ARGS = parse_arguments()
if ARGS.blas:
    print(f"{os.cpu_count()} cores, load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    sys.exit(compare_blas_threads(ARGS.rounds))
if ARGS.threads is not None:  # must happen before numpy loads its BLAS
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[variable] = str(ARGS.threads)

import numpy as np  # noqa: E402
from sklearn.exceptions import ConvergenceWarning  # noqa: E402
from sklearn.linear_model import LogisticRegression  # noqa: E402
from sklearn.multiclass import OneVsRestClassifier  # noqa: E402

from hwlib import accuracy, load_food_cutting, settings, train_test_split  # noqa: E402
from hwlib import logreg  # noqa: E402

KIT = Path(__file__).resolve().parent.parent
NATURAL = KIT / "tests" / "grader" / "natural_solutions"
REPEATS = 3
ALLOWED_GAP = 0.02


def logreg_with(todo, body, name):
    """A fresh copy of ``hwlib/logreg.py`` whose TODO ``todo`` block holds ``body`` (the natural solution
    ``name``), indented like the block, as tests/grader/natural_solutions/README.md describes."""
    lines = Path(logreg.__file__).read_text(encoding="utf-8").split("\n")
    begin = next(i for i, line in enumerate(lines) if line.strip() == f"### BEGIN SOLUTION {todo}")
    end = next(i for i, line in enumerate(lines) if i > begin and line.strip() == f"### END SOLUTION {todo}")
    indent = re.match(r"[ \t]*", lines[begin])[0]
    spliced = [indent + line if line.strip() else "" for line in body.strip("\n").split("\n")]
    module = types.ModuleType(f"hwlib._natural_{todo.replace('.', '_')}")
    # Its own file name, so that a warning or traceback never shows a line of the kit's file as the culprit.
    module.__file__ = f"<hwlib/logreg.py with {name}>"
    exec(compile("\n".join(lines[:begin] + spliced + lines[end + 1:]), module.__file__, "exec"), module.__dict__)
    return module


def timed(function, repeats):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def time_fit(module, X_train, y_train, num_classes, iterations, budget):
    """(seconds, model, note): the fit's time, measured in full or extrapolated from one iteration."""

    def fit(n_iters):
        model = module.MultiClassLogisticRegressionClassifier(X_train.shape[1], num_classes)
        model.fit(X_train, y_train, settings.P2_LEARNING_RATE, n_iters)
        return model

    one, _ = timed(lambda: fit(1), 2)  # the better of two, so that one unlucky iteration does not decide
    if one * iterations > budget:
        return one * iterations, None, f"1 iteration timed (best of 2), x{iterations}"
    repeats = REPEATS if one * iterations < budget / REPEATS else 1
    seconds, model = timed(lambda: fit(iterations), repeats)
    return seconds, model, f"best of {repeats}"


def fit_sklearn(model, X_train, y_train):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        model.fit(X_train, y_train)
    converged = not any(issubclass(w.category, ConvergenceWarning) for w in caught)
    return model, converged


def natural_solutions(styles):
    paths = sorted(NATURAL.glob("2.*.py"))
    if styles != "all":
        wanted = styles.split(",")
        missing = [name for name in wanted if not (NATURAL / f"{name}.py").is_file()]
        if missing:
            raise SystemExit(f"no natural solution named {', '.join(missing)} in {NATURAL}")
        paths = [NATURAL / f"{name}.py" for name in wanted]
    return paths


def main():
    data = load_food_cutting()
    X_train, X_test, y_train, y_test = train_test_split(
        data.features, data.labels, test_fraction=settings.TEST_FRACTION, seed=settings.SPLIT_SEED
    )
    num_classes = len(data.names)
    iterations = ARGS.iterations or settings.P2_NUM_ITERATIONS
    threads = ARGS.threads if ARGS.threads is not None else "library default"
    print(f"data: {data.source}, {len(X_train)} train / {len(X_test)} test cuts, {X_train.shape[1]} features")
    print(f"fit: {num_classes} classes x {iterations} iterations, learning rate {settings.P2_LEARNING_RATE}")
    print(f"BLAS threads: {threads}; {os.cpu_count()} CPUs\n")

    kit_time, kit_model, kit_note = time_fit(logreg, X_train, y_train, num_classes, iterations, budget=float("inf"))
    kit_predictions = kit_model.predict(X_test)
    rows, all_agree = [], True
    for path in natural_solutions(ARGS.styles):
        todo = path.name.split("_")[0]
        if todo in ("2.1.1", "2.2.2", "2.3.2"):
            continue  # fit calls neither the 2.1.1 gradient function nor predict_prob; 2.3.2 is a notebook cell
        module = logreg_with(todo, path.read_text(encoding="utf-8"), path.name)
        seconds, model, note = time_fit(module, X_train, y_train, num_classes, iterations, ARGS.budget)
        test_accuracy = None
        if model is not None:
            predictions = model.predict(X_test)
            all_agree &= bool(np.array_equal(predictions, kit_predictions))
            test_accuracy = accuracy(y_test, predictions)
        rows.append((f"natural {path.stem}", seconds, test_accuracy, note))
    # The kit once more, after the others: on a busy machine the first measurement alone can be unlucky.
    kit_time = min(kit_time, time_fit(logreg, X_train, y_train, num_classes, iterations, budget=float("inf"))[0])
    rows.insert(0, ("kit solution", kit_time, accuracy(y_test, kit_predictions), f"best of {2 * REPEATS}"))

    multinomial_time, (multinomial, multinomial_converged) = timed(
        lambda: fit_sklearn(LogisticRegression(max_iter=1000), X_train, y_train), REPEATS
    )
    ovr_time, (ovr, ovr_converged) = timed(
        lambda: fit_sklearn(OneVsRestClassifier(LogisticRegression(max_iter=1000)), X_train, y_train), REPEATS
    )
    sklearn_rows = [
        ("scikit-learn LogisticRegression (multinomial)", multinomial_time, multinomial.score(X_test, y_test), f"best of {REPEATS}"),
        ("scikit-learn one-vs-rest LogisticRegression", ovr_time, ovr.score(X_test, y_test), f"best of {REPEATS}"),
    ]

    print(f"{'':46s} {'fit time':>10s} {'x kit':>8s} {'test acc':>9s}  how")
    for name, seconds, test_accuracy, note in rows + sklearn_rows:
        shown = "" if test_accuracy is None else f"{test_accuracy:.4f}"
        print(f"{name:46s} {seconds:9.3f}s {seconds / kit_time:7.1f}x {shown:>9s}  {note}")
    print()
    print(f"natural solutions timed in full predict the kit's test labels: {all_agree}")
    print(f"scikit-learn converged: multinomial {multinomial_converged}, one-vs-rest {ovr_converged}")
    kit_accuracy = rows[0][2]
    best_sklearn = max(row[2] for row in sklearn_rows)
    gap = best_sklearn - kit_accuracy
    within = gap <= ALLOWED_GAP
    print(f"kit test accuracy {kit_accuracy:.4f} vs best scikit-learn {best_sklearn:.4f}: "
          f"gap {100 * gap:+.2f} points, within {100 * ALLOWED_GAP:.0f} points: {within}")
    return 0 if within and all_agree else 1


if __name__ == "__main__":
    sys.exit(main())
