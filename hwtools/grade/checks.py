"""What the grader checks for each TODO, on which inputs, and how an answer is judged.

Each TODO's points ride on a few *behaviours* (``Behaviour``): one thing the handout asks,
described in words, worth some points, tested on visible inputs (made here, with a public seed;
students see them and the answer key holds their expected values) and on hidden inputs (made by
``instructor/hidden_checks`` with the instructor's own seed). A behaviour earns its points only
when every one of its inputs passes, visible and hidden, so an answer written for the visible
inputs earns nothing.

Two kinds of judging:

* **exact**, where the handout fixes the computation (eq. (1), eq. (3), the sigmoid, eq. (8), ...):
  the student's values must equal the reference solution's on the same input, within float
  tolerance;
* **by property**, where it does not (which start states ``eval_params`` plays, how the training
  loop is written): the property the handout asks for is checked, with the reference re-scoring
  what the student's code produced (``SERVICES``).

Checks that any code passes (the door checks, shapes made by given code) carry no points.
This module holds the table and the cases; the inputs and judges of each problem live in
``cartpole_checks.py`` and ``logreg_checks.py``, how an answer is judged and shown in
``verdicts.py`` (whose names this module gives too: ``checks.show``, ``checks.Verdict``).
Standard library and numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hwtools.grade.cartpole_checks import (  # noqa: F401 - the table's makers and judges
    FD_TOLERANCE, _coordinate, _learning_rate_services, _policy_row, judge_env_actions,
    judge_eval_distinct, judge_eval_mean, judge_eval_repeat, judge_known_rewards, judge_known_steps,
    judge_learning_rate, judge_real_rewards, make_eval_case, make_fd_steps, make_fd_uniform,
    make_known_training, make_learning_rate, make_policy_states, make_real_training, _coupled,
    central_difference, converged_at,
)
from hwtools.grade.logreg_checks import (  # noqa: F401 - the table's makers and judges
    PROBABILITY_TOLERANCE, SIGMOID_PRECISION, SIGMOID_TOLERANCE, STEP_TOLERANCE, _class_weight,
    _gradient_entry, _sample_row, _sigmoid_entry, _step_weight, make_iterations, make_ll_gradient,
    make_one_vs_rest, make_predict_prob, make_sigmoid_precision, make_sigmoid_shapes,
    make_sigmoid_values, make_step,
)
from hwtools.grade.verdicts import (  # noqa: F401 - given here too: checks.show, checks.Verdict, ...
    EXACTLY, Tolerance, Verdict, difference_words, exact, same_numbers, show, tell_apart,
)

PUBLIC_SEED = 20_240_131  # the visible inputs' seed: students may know it
MOST_KEPT = 0.3  # of a TODO's points, what property points may lift a TODO whose value is wrong to

# The other TODOs whose functions each TODO's check calls. No kit a student's code runs in holds
# their code: the worker's copies are proxies that the reference server answers (``served.py``).
NEEDS = {
    "1.1.1": (),
    "1.2.1": (),
    "1.3.1": ("1.1.1",),
    "1.3.2": ("1.1.1", "1.2.1", "1.3.1"),
    "1.3.3": (),  # only hwlib/settings.py is run with the student's block; the reference server trains
    "2.1.1": ("2.2.1",),
    "2.2.1": (),
    "2.2.2": ("2.2.1",),
    "2.2.3": ("2.1.1", "2.2.1"),
    "2.3.1": ("2.1.1", "2.2.1", "2.2.2", "2.2.3"),
}
SETTINGS_ONLY = {"1.3.3": ("hwlib/settings.py",)}  # TODOs whose kit holds only these files
# The other TODOs whose code a check runs in the student edition's preview, which has no reference:
# its server is the student's own kit, and 1.3.3's training run is the student's 1.1.1-1.3.2 (blame.py).
PREVIEW_NEEDS = NEEDS | {"1.3.3": ("1.1.1", "1.2.1", "1.3.1", "1.3.2")}


@dataclass(frozen=True)
class Behaviour:
    """One graded behaviour of a TODO."""

    todo: str
    key: str
    points: float
    description: str
    probe: str
    make: object  # make(rng, variant) -> the arguments of one case
    judge: object  # judge(args, result, expected_values, services) -> Verdict
    visible_count: int = 2
    services: object = None  # services(args, result) -> [(probe, args)]: reference runs the judge needs
    exact: bool = False  # judged against the reference's values on the same input
    judged_on: str = ""  # the key of another behaviour of the TODO whose cases this one judges (it has none of its own)
    beside: str = ""  # a property of the value behaviour with this key: its points lift a wrong value to MOST_KEPT at most

    @property
    def id(self):
        return f"{self.todo}/{self.key}"

    def visible_cases(self):
        rng = np.random.default_rng([PUBLIC_SEED, _number(self.id)])
        return [self.make(rng, variant) for variant in range(self.visible_count)]


def _number(text):
    return int.from_bytes(text.encode(), "little") % (2**63)



# --------------------------------------------------------------------------------------------
# The table
# --------------------------------------------------------------------------------------------

BEHAVIOURS = (
    Behaviour("1.1.1", "equation-1", 1.5, "policy(obs) is 1 exactly where params . obs < 0, else 0 (equation (1)): on "
              "random parameters and states, and on scores of exactly 0 (the tie: action 0, the < is strict) and "
              "just above and below 0, mixed in among them", "policy_choices", make_policy_states,
              exact("actions", EXACTLY, _policy_row), exact=True),
    Behaviour("1.1.1", "env-action", 0.5, "the right actions, each one env.step takes: the int 0 or 1 (a Python bool "
              "or a numpy integer works too; a float or a numpy bool does not)", "policy_choices", make_policy_states,
              judge_env_actions, visible_count=1, exact=True),
    Behaviour("1.2.1", "equation-3", 7, "central differences, equation (3), with a different step h_i for each "
              "coordinate: only coordinate i moves, by +-h_i, and the difference is divided by 2 h_i; on functions "
              "where a forward difference, or a point other than x, is off (the answer: N numbers, shaped like x "
              "or in a list)", "finite_diff", make_fd_steps, exact("gradient", FD_TOLERANCE, _coordinate),
              exact=True),
    Behaviour("1.2.1", "one-step", 3, "central differences with one step h for every coordinate (h a number or "
              "equal steps), also for a single number x (a number or one number in a list or array)",
              "finite_diff", make_fd_uniform, exact("gradient", FD_TOLERANCE, _coordinate), visible_count=3,
              exact=True),
    Behaviour("1.3.1", "mean-reward", 3, "eval_params returns the mean total reward of num_rollouts episodes of "
              "CartPoleLinearPolicy(params), each from its own start state, played with run_policy or in a "
              "gym.make('CartPole-v1') environment (every reset and step is answered and recorded on the "
              "grader's side)", "eval_params", make_eval_case, judge_eval_mean, visible_count=3),
    Behaviour("1.3.1", "different-starts", 1, "the episodes of one evaluation start from different start states "
              "(counts only up to 30% of the TODO while the mean is wrong)", "eval_params", make_eval_case,
              judge_eval_distinct, judged_on="mean-reward", beside="mean-reward"),
    Behaviour("1.3.1", "repeatable", 1, "the same call gives the same number again, from the same start states "
              "(seeded from the seed argument; counts only up to 30% of the TODO while the mean is wrong)",
              "eval_params", make_eval_case, judge_eval_repeat, judged_on="mean-reward", beside="mean-reward"),
    Behaviour("1.3.2", "equation-4", 3, "on a known smooth objective g standing in for eval_params (with a quartic "
              "term, so the step matters), every iteration evaluates g with num_rollouts_per_eval rollouts, takes "
              "the step of equation (4), theta <- theta + learning_rate * (central-difference gradient of g with "
              "step fd_step), and records g of the new parameters", "train_known", make_known_training,
              judge_known_steps),
    Behaviour("1.3.2", "records-reward", 1, "on the same objective, rewards[t] is g of the parameters after update t",
              "train_known", make_known_training, judge_known_rewards, judged_on="equation-4"),
    Behaviour("1.3.2", "real-run", 1, "in a short real CartPole run, every update is equation (4) with central "
              "differences of step fd_step from eval_params calls with num_rollouts_per_eval episodes, and "
              "rewards[t] is eval_params of the parameters after update t (on the grader's records of every "
              "evaluation)", "train_real", make_real_training, judge_real_rewards, visible_count=1),
    Behaviour("1.3.3", "converges", 2, "with your LEARNING_RATE, the notebook's training run (settings.TRAINING_SEED, "
              "from zeros; the note says whose training code it ran) reaches reward 500 within 7 iterations and "
              "stays there", "settings_value", make_learning_rate, judge_learning_rate, visible_count=1,
              services=_learning_rate_services),
    Behaviour("2.1.1", "gradient", 0, "log_likelihood_gradient equals the summed gradient of equation (7), also "
              "where scores are in the hundreds (shown for the grader of the derivation; no automatic points)",
              "ll_gradient", make_ll_gradient, exact("gradient", STEP_TOLERANCE, _gradient_entry), exact=True),
    Behaviour("2.2.1", "values", 1.2, "sigma(z) = 1 / (1 + e^(-z)) for every entry of a row of numbers from -1000 to "
              "1000: 0, +-1, moderate values and far tails, where the values are 0 and 1 and never NaN (warnings are "
              "not failures)", "sigmoid", make_sigmoid_values, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry),
              visible_count=3, exact=True),
    Behaviour("2.2.1", "any-shape", 0.3, "the same for a single number and for arrays of 2 and 3 axes: values shaped "
              "like z", "sigmoid", make_sigmoid_shapes, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry),
              visible_count=3, exact=True),
    Behaviour("2.2.1", "precision", 0.5, "float64 precision where sigma is close to 0 or 1 (20 < |z| <= 50): "
              "sigma(-24.4) = 2.5e-11, not 0, and sigma(24.4) = 1 - 2.5e-11", "sigmoid", make_sigmoid_precision,
              exact("values", SIGMOID_PRECISION, _sigmoid_entry), exact=True),
    Behaviour("2.2.2", "with-bias", 2.5, "predict_prob gives sigma(w~ . [x, 1]) for each row: the constant 1 feature "
              "appended, the bias weight last; also for scores in the hundreds", "predict_prob", make_predict_prob,
              exact("probabilities", PROBABILITY_TOLERANCE, _sample_row), visible_count=3, exact=True),
    Behaviour("2.2.2", "zero-bias", 0.5, "with a zero bias weight, predict_prob gives sigma(w . x) for each row",
              "predict_prob", lambda rng, variant: make_predict_prob(rng, variant, zero_bias=True),
              exact("probabilities", PROBABILITY_TOLERANCE, _sample_row), exact=True),
    Behaviour("2.2.3", "from-zero", 1, "one step of equation (8) from zero weights: w~ += learning_rate * "
              "sum_i (y_i - sigma(w~ . x~_i)) x~_i, the summed gradient", "gradient_step", make_step,
              exact("weights", STEP_TOLERANCE, _step_weight), exact=True),
    Behaviour("2.2.3", "from-weights", 3, "one step of equation (8) from non-zero weights, also where scores are in "
              "the hundreds", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random"),
              exact("weights", STEP_TOLERANCE, _step_weight), visible_count=3, exact=True),
    Behaviour("2.2.3", "two-steps", 1, "two steps in a row: the second starts from the weights the first left in "
              "self.weights", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random", steps=2),
              exact("weights", STEP_TOLERANCE, _step_weight), visible_count=1, exact=True),
    Behaviour("2.3.1", "one-iteration", 1.5, "one iteration of fit from zero weights: classifier c takes one step of "
              "equation (8) on its one-vs-rest labels (1 for class c, 0 for every other class)", "one_vs_rest",
              make_one_vs_rest, exact("weights", STEP_TOLERANCE, _class_weight), exact=True),
    Behaviour("2.3.1", "iterations", 3.5, "2 to 4 iterations of fit, from zero weights and from the weights the "
              "classifiers already have: in every iteration each classifier takes exactly one step, on its own "
              "labels, from where the last one left it", "one_vs_rest", make_iterations,
              exact("weights", STEP_TOLERANCE, _class_weight), visible_count=2, exact=True),
)
BEHAVIOURS_BY_TODO = {}
for _behaviour in BEHAVIOURS:
    BEHAVIOURS_BY_TODO.setdefault(_behaviour.todo, []).append(_behaviour)
GRADED_TODOS = tuple(BEHAVIOURS_BY_TODO)


@dataclass
class CaseSet:
    """The cases of one TODO: ``visible`` and ``hidden`` lists of (case id, behaviour, args)."""

    todo: str
    visible: list = field(default_factory=list)
    hidden: list = field(default_factory=list)

    def requests(self):
        """The worker requests: visible cases first, the hidden ones only once those are answered."""
        phases = [self.visible] + ([self.hidden] if self.hidden else [])
        return [{"cases": [{"id": case_id, "probe": behaviour.probe, "args": args} for case_id, behaviour, args in phase]}
                for phase in phases]


def cases_of(behaviour):
    """The behaviour whose cases ``behaviour`` is judged on (itself, or the one it names)."""
    if not behaviour.judged_on:
        return behaviour
    return next(other for other in BEHAVIOURS_BY_TODO[behaviour.todo] if other.key == behaviour.judged_on)


def case_set(todo, hidden_module=None):
    cases = CaseSet(todo)
    for behaviour in BEHAVIOURS_BY_TODO[todo]:
        if behaviour.judged_on:
            continue  # judged on the cases of another behaviour
        for number, args in enumerate(behaviour.visible_cases()):
            cases.visible.append((f"{behaviour.id}/v{number}", behaviour, args))
        if hidden_module is not None:
            for number, args in enumerate(hidden_module.hidden_cases(behaviour)):
                cases.hidden.append((f"{behaviour.id}/h{number}", behaviour, args))
    return cases
