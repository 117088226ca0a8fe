"""hwlib: the helper library of the Robot Autonomy Homework 1 notebook kit."""

# Problem 1: CartPole policy search by finite differences
from hwlib.cartpole import CartPoleLinearPolicy, play_episode, random_policy_rewards, run_episodes, run_policy
from hwlib.finite_diff import batched_finite_diff, scalar_finite_diff
from hwlib.policy_search import (
    eval_params,
    iterations_to_converge,
    learning_rate_sweep,
    train_cartpole_policies,
    train_cartpole_policy,
)
