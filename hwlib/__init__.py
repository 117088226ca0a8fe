"""hwlib: the helper library of the Robot Autonomy Homework 1 notebook kit.

The files of this folder are the homework: the TODOs are in ``cartpole.py``, ``finite_diff.py``,
``policy_search.py``, ``settings.py`` and ``logreg.py``; ``training.py``, ``landscape.py``,
``widgets.py`` (the slider panel), ``food_data.py`` and ``plots/`` are given code the notebooks
call. ``machinery/`` is what makes plain code fast and checks it: you need not open it.
"""

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
