"""The handout's TODOs, their points and where their code lives: the one table the grader, the
release tool and the report read. Plain data; importing it runs nothing of the homework.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Todo:
    """One TODO of the handout and how its points are given."""

    id: str
    title: str
    auto: float  # points the grader decides
    manual: float = 0.0  # points a person gives
    manual_what: str = ""  # what that person grades
    code: str = ""  # where the student's code goes: "file: function" (library) or "notebook: cell"


TODOS = (
    Todo("1.1.1", "linear policy, eq. (1)", 2, code="hwlib/cartpole.py: CartPoleLinearPolicy.__call__"),
    Todo("1.1.2", "hand-tuning the policy", 0, 2, "report: parameters tried and the behaviour they gave",
         code="notebooks/p1_cartpole_finite_difference.ipynb: the `tried` cell"),
    Todo("1.1.3", "1000 random policies", 0, 1, "report: reward histogram, share of policies at 500",
         code="notebooks/p1_cartpole_finite_difference.ipynb: the random-policy cell"),
    Todo("1.2.1", "central finite differences, eq. (3)", 10, code="hwlib/finite_diff.py: scalar_finite_diff"),
    Todo("1.3.1", "parameter evaluation g(theta)", 5, code="hwlib/policy_search.py: eval_params"),
    Todo("1.3.2", "gradient ascent, eq. (4)", 5, code="hwlib/policy_search.py: train_cartpole_policy"),
    Todo("1.3.3", "learning rate: converges within 7 iterations", 2, 3,
         "report: learning rate, final parameters, training curve", code="hwlib/settings.py: LEARNING_RATE"),
    Todo("2.1.1", "derivation of the log-likelihood gradient", 0, 10, "the derivation in the p2 notebook",
         code="notebooks/p2_food_cutting_logistic_regression.ipynb: the 2.1.1 cell; hwlib/logreg.py: log_likelihood_gradient"),
    Todo("2.2.1", "sigmoid", 2, code="hwlib/logreg.py: sigmoid"),
    Todo("2.2.2", "predict_prob with the bias feature", 3, code="hwlib/logreg.py: TwoClassLogisticRegressionClassifier.predict_prob"),
    Todo("2.2.3", "gradient ascent step, eq. (8)", 5,
         code="hwlib/logreg.py: TwoClassLogisticRegressionClassifier.gradient_ascent_step"),
    Todo("2.3.1", "one-vs-rest fit", 5, code="hwlib/logreg.py: MultiClassLogisticRegressionClassifier.fit"),
    Todo("2.3.2", "training run", 0, 5, "report: training curve, final train and test accuracy",
         code="notebooks/p2_food_cutting_logistic_regression.ipynb: the 2.3.2 training cell"),
)
TODO_BY_ID = {todo.id: todo for todo in TODOS}
AUTO_POINTS = sum(todo.auto for todo in TODOS)  # 39
MANUAL_POINTS = sum(todo.manual for todo in TODOS)  # 21
