"""Every answer the handout asks to report: ``compute_answers`` gathers them from the checked notebook values
(a plain, JSON-ready dict), ``answers_markdown`` writes them as answers.md, one section per handout item,
and the ``*_text`` functions print numbers in the formats the notebooks print them (docs/report.md;
answers.html, answers.pdf and answers.tex are made from these).
"""

from __future__ import annotations

import html

import numpy as np

from hwlib import settings
from hwlib.cartpole import (
    MAX_EPISODE_REWARD,
    THETA_THRESHOLD_RADIANS,
    X_THRESHOLD,
    CartPoleLinearPolicy,
    play_episode,
    run_policy,
)
from hwlib.policy_search import iterations_to_converge
from hwtools.report.figures import FIGURE_CAPTIONS
from hwtools.report.notebooks import DERIVATION_TODO

NAME_BLANK = "_" * 28
NAME_LABEL = "Name / Andrew ID:"
TITLE = "Robot Autonomy — Homework 1: answers"




def rewards_text(rewards):
    """Rewards per iteration as the report and the p1 notebook print them: one decimal each."""
    return ", ".join(f"{reward:.1f}" for reward in rewards)


def final_params_text(params):
    """Learned parameters as the report and the p1 notebook print them: three decimals each."""
    return "[" + ", ".join(f"{value:.3f}" for value in params) + "]"


def tried_params_text(params):
    """Parameters tried by hand, as typed (shortest form)."""
    return "(" + ", ".join(f"{value:g}" for value in params) + ")"


def describe_episode(episode):
    """What the cart does in ``episode``, in words: how it pushes and how the episode ends."""
    right = float(np.mean(episode.actions)) if episode.num_steps else 0.0
    if right == 0.0:
        pushes = "pushes left at every step"
    elif right == 1.0:
        pushes = "pushes right at every step"
    else:
        pushes = f"pushes right in {right:.0%} of the steps and left in the rest"
    cart_x, _, angle, _ = episode.states[-1]
    steps = episode.num_steps
    if episode.total_reward >= MAX_EPISODE_REWARD:
        low, high = episode.states[:, 0].min(), episode.states[:, 0].max()
        ends = f"balances the pole for all {steps} steps, the cart staying between x = {low:.2f} and {high:.2f}"
    elif abs(cart_x) > X_THRESHOLD:
        ends = f"the cart runs off the {'right' if cart_x > 0 else 'left'} end of the track after {steps} steps"
    elif abs(angle) > THETA_THRESHOLD_RADIANS:
        ends = f"the pole falls to the {'right' if angle > 0 else 'left'} ({np.degrees(angle):+.1f}°) after {steps} steps"
    else:
        ends = f"the episode ends after {steps} steps"
    return f"{pushes}; {ends}"


def compute_answers(p1, p2):
    """Every number the handout asks to report, as a plain dict (JSON-serialisable), from the notebooks' values.

    Only the 1.1.2 table plays episodes here: one per seed of ``settings.HAND_TUNING_SEEDS`` for each
    parameter vector the student tried, to describe what it does.
    """
    seeds = list(settings.HAND_TUNING_SEEDS)
    tried = []
    for name, params in p1.tried.items():
        tried.append({
            "name": name,
            "params": [float(value) for value in params],
            "behaviour": describe_episode(play_episode(CartPoleLinearPolicy(params), seed=seeds[0])),
            "rewards": [int(run_policy(CartPoleLinearPolicy(params), seed=seed)) for seed in seeds],
        })
    rewards = p1.random_rewards
    num_at_max = int(np.sum(rewards >= MAX_EPISODE_REWARD))
    converged_at = iterations_to_converge(p1.training_rewards)
    deadline = settings.CONVERGENCE_DEADLINE
    accuracies = p2.train_accuracies
    return {
        "p1_hand_tuning": {"seeds": seeds, "tried": tried},
        "p1_random_policies": {
            "num_policies": len(rewards),
            "num_at_max": num_at_max,
            "share_at_max": num_at_max / len(rewards),
            "median_reward": float(np.median(rewards)),
        },
        "p1_training": {
            "learning_rate": p1.learning_rate,
            "num_iterations": len(p1.training_rewards) - 1,
            "num_rollouts_per_eval": settings.NUM_ROLLOUTS,
            "rewards": [float(reward) for reward in p1.training_rewards],
            "final_params": [float(value) for value in p1.final_params],
            "converged_at": converged_at,
            "deadline": deadline,
            "converged_within_deadline": converged_at is not None and converged_at <= deadline,
        },
        "p1_learning_rate_sweep": {
            "learning_rates": [float(rate) for rate in p1.sweep.learning_rates],
            "num_seeds": len(p1.sweep.seeds),
            "deadline": p1.sweep.deadline,
            "converged_fraction": [float(fraction) for fraction in p1.sweep.converged_fraction],
        },
        "p2_results": {
            "data_source": p2.data_source,
            "data_file": p2.data_path,
            "num_train": p2.num_samples - len(p2.y_test),
            "num_test": len(p2.y_test),
            "learning_rate": settings.P2_LEARNING_RATE,
            "num_iterations": len(accuracies) - 1,
            "final_train_accuracy": float(accuracies[-1]),
            "test_accuracy": p2.test_accuracy,
            "first_iteration_above_99": p2.first_above_99,
            "target_iterations": settings.TARGET_ITERATIONS,
        },
        "p2_derivation": p2.derivation,
    }


SYNTHETIC_NOTE = ("the course's data.npz was not found in the kit's data/ folder, so the kit's synthetic data set with the"
                  " same layout was used: these are not the numbers of the real data.")


def name_line(name):
    return f"{NAME_LABEL} {name if name else NAME_BLANK}"


def _deadline_note(deadline, met):
    return f"(deadline {deadline}: {'met' if met else 'missed'})"


def answer_text(answers):
    """The answers' numbers as text, in the formats the notebooks print them: the one place where answers.md and
    answers.tex take them from. A dict of strings (lists of them for the tables)."""
    hand, rand, train = answers["p1_hand_tuning"], answers["p1_random_policies"], answers["p1_training"]
    sweep, food = answers["p1_learning_rate_sweep"], answers["p2_results"]
    seeds, converged, first = hand["seeds"], train["converged_at"], food["first_iteration_above_99"]
    return {
        "seed": f"{seeds[0]}",
        "seed_range": f"{seeds[0]}–{seeds[-1]}" if len(seeds) > 1 else f"{seeds[0]}",
        "tried": [
            {"name": str(entry["name"]), "params": tried_params_text(entry["params"]), "behaviour": entry["behaviour"],
             "rewards": ", ".join(str(reward) for reward in entry["rewards"])}
            for entry in hand["tried"]
        ],
        "max_reward": f"{MAX_EPISODE_REWARD:g}",  # the episode cap (hwlib/settings.py)
        "num_at_max": f"{rand['num_at_max']}",
        "num_policies": f"{rand['num_policies']}",
        "share_at_max": f"{rand['share_at_max']:.1%}",
        "median_reward": f"{rand['median_reward']:.1f}",
        "learning_rate": f"{train['learning_rate']:g}",
        "final_params": final_params_text(train["final_params"]),
        "converged_at": f"{converged}",
        "converged_note": _deadline_note(train["deadline"], train["converged_within_deadline"])
        if converged is not None else f"(not within {train['num_iterations']} iterations)",
        "rewards": rewards_text(train["rewards"]),
        "num_rollouts": f"{train['num_rollouts_per_eval']}",
        "sweep_seeds": f"{sweep['num_seeds']}",
        "sweep_deadline": f"{sweep['deadline']}",
        "sweep_rates": [f"{rate:.1e}" for rate in sweep["learning_rates"]],
        "sweep_converged": [f"{fraction:.0%}" for fraction in sweep["converged_fraction"]],
        "data_source": food["data_source"],
        "data_file": food["data_file"],
        "num_train": f"{food['num_train']}",
        "num_test": f"{food['num_test']}",
        "p2_learning_rate": f"{food['learning_rate']:g}",
        "p2_iterations": f"{food['num_iterations']}",
        "final_train_accuracy": f"{food['final_train_accuracy']:.3f}",
        "test_accuracy": f"{food['test_accuracy']:.3f}",
        "first_above_99": f"{first}",
        "first_note": _deadline_note(food["target_iterations"], first <= food["target_iterations"])
        if first is not None else f"(never within {food['num_iterations']} iterations)",
    }


def answers_markdown(answers, name=None):
    """answers.md: each handout question that asks for a report item, answered."""
    text = answer_text(answers)
    lines = [
        f"# {TITLE}",
        "",
        f"**{NAME_LABEL}** {html.escape(name) if name else NAME_BLANK}",
        "",
        "Made by `python -m hwtools.report` from the executed notebooks: every number and figure below is the",
        "notebooks' own (the notebooks are next to this file as HTML).",
        "",
        "## Problem 1: reinforcement learning by finite differences",
        "",
        "### 1.1.2 Parameters tried by hand and the behaviour they gave",
        "",
        "The parameter vectors of the notebook's `tried`. The policy pushes right (action 1) when θᵀs < 0 and left",
        "otherwise; s = (cart position, cart velocity, pole angle, pole angular velocity). What the cart does is",
        f"described for the start state of seed {text['seed']}; the rewards are one episode from each start state of"
        f" seeds {text['seed_range']}.",
        "",
        f"| parameters tried | θ | what the cart does (seed {text['seed']}) | rewards, seeds {text['seed_range']} |",
        "|---|---|---|---|",
    ]
    for row in text["tried"]:
        lines.append(f"| {_table_cell(row['name'])} | {row['params']} | {row['behaviour']} | {row['rewards']} |")
    lines += [
        "",
        "### 1.1.3 Random policies",
        "",
        f"- {text['num_at_max']} of {text['num_policies']} random policies reached the maximum reward of {text['max_reward']}:"
        f" **{text['share_at_max']}**",
        f"- median reward: {text['median_reward']}",
        "",
        _figure("p1_random_policy_histogram.png"),
        "",
        "### 1.3.3 Learning rate and learning curve",
        "",
        f"- learning rate: **{text['learning_rate']}**",
        f"- final parameters: **{text['final_params']}**",
        f"- converged ({text['max_reward']} from then on) at iteration: **{text['converged_at']}** {text['converged_note']}",
        f"- reward per iteration: {text['rewards']}",
        "",
        f"Iteration 0 is before the first update; each reward is the mean of {text['num_rollouts']} episodes.",
        "",
        _figure("p1_training_curve.png"),
        "",
        f"How sensitive is this to the learning rate? The share of {text['sweep_seeds']} seeds that converge within"
        f" {text['sweep_deadline']} iterations:",
        "",
        "| learning rate | " + " | ".join(text["sweep_rates"]) + " |",
        "|---|" + "---|" * len(text["sweep_rates"]),
        "| converged | " + " | ".join(text["sweep_converged"]) + " |",
        "",
        _figure("p1_learning_rate_sweep.png"),
        "",
        "## Problem 2: classification by logistic regression",
        "",
        f"### {DERIVATION_TODO} The gradient of the log-likelihood",
        "",
        "The derivation as written in the notebook:",
        "",
        answers["p2_derivation"] or f"*(not found: the notebook has no {DERIVATION_TODO} heading with an answer under it)*",
        "",
        "### 2.3.2 Training curve and accuracy",
        "",
        f"- data: **{text['data_source']}** — "
        + (f"read from `{text['data_file']}`." if text["data_file"] else SYNTHETIC_NOTE),
        f"- split: {text['num_train']} training and {text['num_test']} test samples;"
        f" learning rate {text['p2_learning_rate']}, {text['p2_iterations']} iterations from zero weights.",
        f"- final train accuracy: **{text['final_train_accuracy']}**",
        f"- test accuracy: **{text['test_accuracy']}**",
        f"- first iteration with train accuracy above 99%: **{text['first_above_99']}** {text['first_note']}",
        "",
        _figure("p2_training_curve.png"),
        "",
        _figure("p2_confusion_matrix.png"),
        "",
    ]
    return "\n".join(lines)


def _table_cell(text):
    return html.escape(str(text)).replace("|", "\\|")


def _figure(name):
    return f"![{FIGURE_CAPTIONS[name]}]({name})"
