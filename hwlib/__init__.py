"""hwlib: the helper library of the Robot Autonomy Homework 1 notebook kit.

The files of this folder are the homework: the TODOs are in ``cartpole.py``, ``finite_diff.py``,
``policy_search.py``, ``settings.py`` and ``logreg.py``; ``training.py``, ``landscape.py``,
``widgets.py`` (the slider panel), ``food_data.py`` and ``plots/`` are given code the notebooks
call. ``machinery/`` is what makes plain code fast and checks it: you need not open it.

Importing ``hwlib`` before numpy keeps numpy's matrix library (OpenBLAS) to one thread unless
``OPENBLAS_NUM_THREADS`` is set: on a shared 2-core laptop one thread is several times faster
(``benchmarks/bench_logreg.py --blas``: one fit of 2.3.2 took 2.6 s with one thread and 10 s with
two, 2026-12, 2 cores at load 3-4). The library reads the setting once, when numpy loads, so the
notebooks import ``hwlib`` first.
"""

import os

for _variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
del _variable

# Problem 1: CartPole policy search by finite differences
from hwlib import settings
from hwlib.cartpole import CartPoleLinearPolicy, play_episode, random_policy_rewards, run_policy
from hwlib.finite_diff import scalar_finite_diff
from hwlib.machinery.todos import TodoNotDone
from hwlib.policy_search import TrainingRun, eval_params, iterations_to_converge, train_cartpole_policy
from hwlib.training import SweepResult, learning_rate_sweep, run_training

# Problem 2: food-cutting classification by one-vs-rest logistic regression.
from hwlib.food_data import (
    FOOD_NAMES,
    FoodCuttingData,
    find_audio_examples,
    load_food_cutting,
    make_synthetic_food_cutting,
)
from hwlib.logreg import (
    MultiClassLogisticRegressionClassifier,
    TwoClassLogisticRegressionClassifier,
    accuracy,
    add_bias_feature,
    confusion_matrix,
    first_iteration_above,
    gradient_check,
    log_likelihood,
    log_likelihood_gradient,
    per_class_accuracy,
    sigmoid,
    train_test_split,
)
