"""Policy search for CartPole by gradient ascent with finite-difference gradients (handout 1.3).

g(theta), the expected reward of the linear policy, is estimated by the mean reward of a few
episodes (``eval_params``, TODO 1.3.1); its gradient by central differences
(``scalar_finite_diff``, TODO 1.2.1); and the parameters climb it with equation (4),
``theta <- theta + learning_rate * grad`` (``train_cartpole_policy``, TODO 1.3.2).

| setting (``hwlib/settings.py``) | value   | why                                                       |
|-------------------------|---------|-----------------------------------------------------------|
| start parameters        | zeros   | the "always left" policy: every run starts from one place |
| ``FD_STEP``             | 0.5     | the policy only sees the direction of theta, so a step must be large enough to tip some actions |
| ``NUM_ROLLOUTS``        | 20      | with 10, one unlucky start decides too often              |
| ``LEARNING_RATE``       | TODO 1.3.3 | a rate with which training converges within 7 iterations |
| start states            | shared within an iteration | every evaluation of iteration t uses the seeds of ``iteration_seed(seed, t)`` (common random numbers) |

The notebook runs your ``train_cartpole_policy`` through ``hwlib/training.py`` (one run, and every
run of the learning-rate sweep), which plays the episodes your code asks for many at a time: the
same rewards, much sooner.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hwlib import settings
from hwlib.cartpole import MAX_EPISODE_REWARD, NUM_OBSERVATIONS, CartPoleLinearPolicy, run_policy
from hwlib.finite_diff import scalar_finite_diff
from hwlib.machinery.todos import TodoNotDone
from hwlib.machinery.validation import as_float_array, check_count, check_finite, check_params, check_positive_number, check_seed

SEEDS_PER_ITERATION = 1_000  # iteration t of a run with seed s evaluates on seeds from iteration_seed(s, t) on
SEEDS_PER_RUN = 1_000_000


def eval_params(params, num_rollouts=settings.NUM_ROLLOUTS, seed=0):
    """g(theta): the mean total reward of ``num_rollouts`` episodes of ``CartPoleLinearPolicy(params)``.

    Episode k (k = 0, ..., num_rollouts - 1) is ``run_policy(policy, seed=seed + k)``, so the same
    call always gives the same number. Returns a float.
    """
    policy = CartPoleLinearPolicy(params)  # checks params: 4 finite numbers
    num_rollouts = check_count(num_rollouts, "num_rollouts")
    seed = check_seed(seed, "seed")
    mean_reward = 0.0
    ### BEGIN SOLUTION 1.3.1
    ### HINT: play num_rollouts episodes of policy with run_policy (episode k from seed + k) and set mean_reward to the average of their total rewards
    total_reward = 0.0
    for k in range(num_rollouts):
        total_reward += run_policy(policy, seed=seed + k)
    mean_reward = total_reward / num_rollouts
    ### END SOLUTION 1.3.1
    return float(mean_reward)


def iteration_seed(seed, iteration):
    """The first episode seed of iteration ``iteration`` of the training run with ``seed``."""
    return check_seed(seed, "seed") * SEEDS_PER_RUN + check_seed(iteration, "iteration") * SEEDS_PER_ITERATION


class TrainingRun(NamedTuple):
    """What ``train_cartpole_policy`` learned: the final policy, the reward before training
    (``rewards[0]``) and after each update (``rewards[t]`` after t updates), and the parameters
    at the same moments (``params_history[t]``, shape (T + 1, 4))."""

    policy: CartPoleLinearPolicy
    rewards: np.ndarray
    params_history: np.ndarray


def train_cartpole_policy(
    num_training_iterations=settings.NUM_TRAINING_ITERATIONS,
    num_rollouts_per_eval=settings.NUM_ROLLOUTS,
    learning_rate=None,
    fd_step=settings.FD_STEP,
    seed=settings.TRAINING_SEED,
    initial_params=None,
):
    """Train one linear policy by gradient ascent on g(theta), equation (4). Returns a ``TrainingRun``.

    ``learning_rate`` defaults to ``settings.LEARNING_RATE`` (TODO 1.3.3) and ``initial_params``
    to zeros. Every evaluation of g in iteration t uses the same start states, the episodes of
    ``eval_params(..., seed=iteration_seed(seed, t))``.
    """
    num_training_iterations = check_count(num_training_iterations, "num_training_iterations")
    num_rollouts_per_eval = check_count(num_rollouts_per_eval, "num_rollouts_per_eval")
    learning_rate = check_learning_rate(settings.LEARNING_RATE if learning_rate is None else learning_rate)
    fd_step = check_positive_number(fd_step, "fd_step")
    seed = check_seed(seed, "seed")
    params = np.zeros(NUM_OBSERVATIONS) if initial_params is None else check_params(initial_params, "initial_params").copy()

    rewards = [eval_params(params, num_rollouts_per_eval, seed=iteration_seed(seed, 0))]  # before training
    params_history = [params.copy()]
    for iteration in range(1, num_training_iterations + 1):
        eval_seed = iteration_seed(seed, iteration)  # the start states of every evaluation in this iteration
        ### BEGIN SOLUTION 1.3.2
        ### HINT: estimate the gradient of g(p) = eval_params(p, num_rollouts_per_eval, seed=eval_seed) at params with scalar_finite_diff (steps fd_step), update params by equation (4), then append g of the new params to rewards
        def g(p):
            return eval_params(p, num_rollouts_per_eval, seed=eval_seed)

        gradient = scalar_finite_diff(g, params, fd_step)
        params = params + learning_rate * gradient
        rewards.append(g(params))
        ### END SOLUTION 1.3.2
        params_history.append(np.array(params, dtype=np.float64))
    return TrainingRun(CartPoleLinearPolicy(params), np.array(rewards, dtype=np.float64), np.array(params_history))


def iterations_to_converge(rewards, max_reward=MAX_EPISODE_REWARD):
    """The first iteration from which every recorded reward is the maximum, or None.

    ``rewards[t]`` is the reward after t updates, so the answer counts updates.
    """
    rewards = check_finite(as_float_array(rewards, "rewards"), "rewards")
    if rewards.ndim != 1 or rewards.size == 0:
        raise ValueError(f"rewards must be a non-empty 1-d array, got shape {rewards.shape}")
    below = np.flatnonzero(rewards < max_reward)
    first_good = 0 if below.size == 0 else int(below[-1]) + 1
    return first_good if first_good < rewards.size else None


def converged_within(rewards, deadline=settings.CONVERGENCE_DEADLINE):
    """True when the run reached the maximum reward by iteration ``deadline`` and stayed there."""
    iteration = iterations_to_converge(rewards)
    return iteration is not None and iteration <= deadline


def check_learning_rate(learning_rate, name="learning_rate"):
    """A learning rate: a finite number > 0. None (``settings.LEARNING_RATE`` before TODO 1.3.3) raises ``TodoNotDone``."""
    if learning_rate is None:
        raise TodoNotDone("1.3.3")
    return check_positive_number(learning_rate, name)
