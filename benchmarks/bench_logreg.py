"""Problem 2 benchmark: the kit's one-vs-rest fit against loops and against scikit-learn.

Run from the kit's root, after ``pip install -r benchmarks/requirements-bench.txt``:

    python benchmarks/bench_logreg.py              # BLAS with its default number of threads
    python benchmarks/bench_logreg.py --threads 1  # single-threaded BLAS

It uses the same data as the notebook (the course's ``data/data.npz`` if present, else the
synthetic stand-in) and the same 70/30 split, and prints in one run:

| line                        | what is timed                                                    |
|-----------------------------|------------------------------------------------------------------|
| kit, per-class loop         | ``fit`` as the handout describes it, 70 iterations (best of 3)   |
| kit, vectorized             | ``fit(..., vectorized=True)``, all classes per matrix product    |
| per-sample Python loop      | the same updates summed sample by sample; 1 iteration timed, x70 |
| scikit-learn, multinomial   | ``LogisticRegression()`` (lbfgs, L2, C=1), up to 1000 iterations  |
| scikit-learn, one-vs-rest   | ``OneVsRestClassifier(LogisticRegression())``, same settings      |

and the test accuracies. Exits with status 1 if the kit's test accuracy is more than 2 points
below scikit-learn's.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings


def parse_arguments():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=None, help="BLAS threads (default: the library's own choice)")
    parser.add_argument("--iterations", type=int, default=70, help="training iterations of the kit (default 70)")
    return parser.parse_args()


ARGS = parse_arguments()
if ARGS.threads is not None:  # must happen before numpy loads its BLAS
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[variable] = str(ARGS.threads)

import numpy as np  # noqa: E402
from sklearn.exceptions import ConvergenceWarning  # noqa: E402
from sklearn.linear_model import LogisticRegression  # noqa: E402
from sklearn.multiclass import OneVsRestClassifier  # noqa: E402

from hwlib import MultiClassLogisticRegressionClassifier, accuracy, load_food_cutting, train_test_split  # noqa: E402

LEARNING_RATE = 0.1
REPEATS = 3
ALLOWED_GAP = 0.02


def best_time(function, repeats=REPEATS):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def fit_kit(X_train, y_train, num_classes, iterations, vectorized):
    model = MultiClassLogisticRegressionClassifier(X_train.shape[1], num_classes)
    model.fit(X_train, y_train, LEARNING_RATE, iterations, vectorized=vectorized)
    return model


def per_sample_iteration(weights, X_aug, labels):
    """One outer iteration with a Python loop over samples: the same update, summed by hand."""
    for class_index in range(weights.shape[1]):
        gradient = np.zeros(weights.shape[0])
        column = weights[:, class_index]
        for sample, label in zip(X_aug, labels):
            probability = 0.5 * (1.0 + math.tanh(0.5 * float(sample @ column)))  # sigma, overflow-free
            gradient += (float(label == class_index) - probability) * sample
        weights[:, class_index] += LEARNING_RATE * gradient


def fit_sklearn(model, X_train, y_train):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        model.fit(X_train, y_train)
    converged = not any(issubclass(w.category, ConvergenceWarning) for w in caught)
    return model, converged


def main():
    data = load_food_cutting()
    X_train, X_test, y_train, y_test = train_test_split(data.features, data.labels, test_fraction=0.3, seed=0)
    num_classes = len(data.names)
    iterations = ARGS.iterations
    threads = ARGS.threads if ARGS.threads is not None else "library default"
    print(f"data: {data.source}, {len(X_train)} train / {len(X_test)} test cuts, {X_train.shape[1]} features")
    print(f"BLAS threads: {threads}; {os.cpu_count()} CPUs; best of {REPEATS} runs\n")

    loop_time, loop_model = best_time(lambda: fit_kit(X_train, y_train, num_classes, iterations, vectorized=False))
    vector_time, vector_model = best_time(lambda: fit_kit(X_train, y_train, num_classes, iterations, vectorized=True))
    X_aug = np.hstack([X_train, np.ones((len(X_train), 1))])
    sample_weights = np.zeros((X_aug.shape[1], num_classes))
    one_iteration, _ = best_time(lambda: per_sample_iteration(sample_weights, X_aug, y_train), repeats=1)
    sample_time = one_iteration * iterations

    multinomial_time, (multinomial, multinomial_converged) = best_time(
        lambda: fit_sklearn(LogisticRegression(max_iter=1000), X_train, y_train)
    )
    ovr_time, (ovr, ovr_converged) = best_time(
        lambda: fit_sklearn(OneVsRestClassifier(LogisticRegression(max_iter=1000)), X_train, y_train)
    )

    kit_accuracy = accuracy(y_test, loop_model.predict(X_test))
    same = np.array_equal(loop_model.predict(X_test), vector_model.predict(X_test))
    rows = [
        (f"kit, per-class loop, {iterations} iterations", loop_time, kit_accuracy),
        (f"kit, vectorized, {iterations} iterations", vector_time, accuracy(y_test, vector_model.predict(X_test))),
        (f"per-sample Python loop, {iterations} iterations (1 timed)", sample_time, None),
        ("scikit-learn LogisticRegression (multinomial)", multinomial_time, multinomial.score(X_test, y_test)),
        ("scikit-learn one-vs-rest LogisticRegression", ovr_time, ovr.score(X_test, y_test)),
    ]
    print(f"{'':58s} {'fit time':>10s} {'test acc':>9s}")
    for name, seconds, test_accuracy in rows:
        shown = "" if test_accuracy is None else f"{test_accuracy:.4f}"
        print(f"{name:58s} {seconds:9.3f}s {shown:>9s}")
    print()
    print(f"per-sample loop / kit per-class loop: {sample_time / loop_time:8.0f}x slower")
    print(f"kit per-class loop / vectorized:      {loop_time / vector_time:8.2f}x")
    print(f"vectorized and per-class loop predict the same test labels: {same}")
    print(f"scikit-learn converged: multinomial {multinomial_converged}, one-vs-rest {ovr_converged}")
    best_sklearn = max(rows[3][2], rows[4][2])
    gap = best_sklearn - kit_accuracy
    within = gap <= ALLOWED_GAP
    print(f"kit test accuracy {kit_accuracy:.4f} vs best scikit-learn {best_sklearn:.4f}: "
          f"gap {100 * gap:+.2f} points, within {100 * ALLOWED_GAP:.0f} points: {within}")
    return 0 if within else 1


if __name__ == "__main__":
    sys.exit(main())
