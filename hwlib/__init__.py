"""hwlib: the helper library of the Robot Autonomy Homework 1 notebook kit."""

# Problem 1: CartPole policy search by finite differences
from hwlib import settings
from hwlib._todo import TodoNotDone
from hwlib.cartpole import CartPoleLinearPolicy, play_episode, random_policy_rewards, run_episodes, run_policy
from hwlib.finite_diff import scalar_finite_diff
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
