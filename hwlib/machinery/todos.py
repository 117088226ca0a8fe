"""The handout's TODOs as data, and ``TodoNotDone``, the error a TODO's starting code raises.

``TODOS`` is the kit's one TODO table: its points (each check's too: ``checks``, which the grader
reads and which must add up to ``auto``; the grader refuses to start otherwise) and where each
TODO's code goes. Every reader
uses it: ``TodoNotDone``'s two lines below, and the grader, the hand-in, the release tool and the
report through ``hwtools/todos.py``, which loads this file by its path (the grader's trusted side
never imports ``hwlib``). So this module imports nothing but the standard library.

Every TODO stub in the student edition is its hint as a comment and ``raise TodoNotDone("1.1.1")``;
the module-level 1.3.3 is ``LEARNING_RATE = None``, and whatever reads it raises
``TodoNotDone("1.3.3")``. In a notebook IPython shows the two lines of ``_render_traceback_``
instead of a traceback, so a cell that needs an unwritten TODO says which one, at the top of its
output; in pytest the same two lines are the error's message.
"""

from __future__ import annotations

from dataclasses import dataclass

P1 = "notebooks/p1_cartpole_finite_difference.ipynb"
P2 = "notebooks/p2_food_cutting_logistic_regression.ipynb"


@dataclass(frozen=True)
class Todo:
    """One TODO of the handout and how its points are given."""

    id: str
    title: str
    auto: float  # points the grader decides: the sum of ``checks``
    manual: float = 0.0  # points a person gives
    manual_what: str = ""  # what that person grades
    code: str = ""  # where the code goes: "file: what", several joined by "; "
    checks: tuple = ()  # (check key, points) of each graded check (hwtools/grade/checks/), in order

    @property
    def check_points(self):
        """``{check key: points}``."""
        return dict(self.checks)

    @property
    def where(self):
        """``(file, what)`` of the part with the TODO's stub: its library file if it has one, else its notebook."""
        parts = [part.partition(": ")[::2] for part in self.code.split("; ")]
        return next((part for part in parts if part[0].endswith(".py")), parts[0])


TODOS = (
    Todo("1.1.1", "linear policy, eq. (1)", 2, code="hwlib/cartpole.py: CartPoleLinearPolicy.__call__",
         checks=(("equation-1", 1.5), ("env-action", 0.5))),
    Todo("1.1.2", "hand-tuning the policy", 0, 2, "report: parameters tried and the behaviour they gave",
         code=f"{P1}: the `tried` cell"),
    Todo("1.1.3", "1000 random policies", 0, 1, "report: reward histogram, share of policies at the maximum",
         code=f"{P1}: the random-policy cell"),
    Todo("1.2.1", "central finite differences, eq. (3)", 10, code="hwlib/finite_diff.py: scalar_finite_diff",
         checks=(("equation-3", 7), ("one-step", 3))),
    Todo("1.3.1", "parameter evaluation g(theta)", 5, code="hwlib/policy_search.py: eval_params",
         checks=(("mean-reward", 3), ("different-starts", 1), ("repeatable", 1))),
    Todo("1.3.2", "gradient ascent, eq. (4)", 5, code="hwlib/policy_search.py: the loop of train_cartpole_policy",
         checks=(("equation-4", 3), ("records-reward", 1), ("real-run", 1))),
    Todo("1.3.3", "learning rate: converges within 7 iterations", 2, 3,
         "report: learning rate, final parameters, training curve", code="hwlib/settings.py: LEARNING_RATE",
         checks=(("converges", 2),)),
    Todo("2.1.1", "derivation of the log-likelihood gradient", 0, 10, "the derivation in the p2 notebook",
         code=f"{P2}: the 2.1.1 cell; hwlib/logreg.py: log_likelihood_gradient",
         checks=(("gradient", 0),)),
    Todo("2.2.1", "sigmoid", 2, code="hwlib/logreg.py: sigmoid",
         checks=(("values", 1.2), ("any-shape", 0.3), ("precision", 0.5))),
    Todo("2.2.2", "predict_prob with the bias feature", 3, code="hwlib/logreg.py: TwoClassLogisticRegressionClassifier.predict_prob",
         checks=(("with-bias", 2.5), ("zero-bias", 0.5))),
    Todo("2.2.3", "gradient ascent step, eq. (8)", 5,
         code="hwlib/logreg.py: TwoClassLogisticRegressionClassifier.gradient_ascent_step",
         checks=(("from-zero", 1), ("from-weights", 3), ("two-steps", 1))),
    Todo("2.3.1", "one-vs-rest fit", 5,
         code="hwlib/logreg.py: the loop over classes in MultiClassLogisticRegressionClassifier.fit",
         checks=(("one-iteration", 1.5), ("iterations", 3.5))),
    Todo("2.3.2", "training run", 0, 5, "report: training curve, final train and test accuracy",
         code=f"{P2}: the 2.3.2 training cell"),
)
TODO_BY_ID = {todo.id: todo for todo in TODOS}
AUTO_POINTS = sum(todo.auto for todo in TODOS)
MANUAL_POINTS = sum(todo.manual for todo in TODOS)
_RED, _PLAIN = "\x1b[1;31m", "\x1b[0m"


class TodoNotDone(NotImplementedError):
    """Raised by the starting code of TODO ``todo`` (e.g. ``"1.1.1"``): the student has not written it yet."""

    def __init__(self, todo):
        self.todo = str(todo)
        super().__init__("\n".join(self.lines()))

    def lines(self):
        """Two lines: which TODO and where its code goes, then what to do."""
        where, what = TODO_BY_ID[self.todo].where if self.todo in TODO_BY_ID else (None, None)
        first = f"TODO {self.todo} is not done yet" + (f": {what} in {where}" if what else "")
        markers = f"### BEGIN TODO {self.todo} and ### END TODO {self.todo}"
        then = "then Kernel → Restart Kernel and Run All Cells."
        if where is None:
            todo = f"Write its code between {markers}, {then}"
        elif where.endswith(".ipynb"):
            todo = f"Write it between {markers} in that cell, {then}"
        elif self.todo == "1.3.3":
            todo = f"Set LEARNING_RATE between {markers} to the rate you chose (or pass learning_rate=...), save, {then}"
        else:
            todo = f"Write it between {markers} there, save, {then}"
        return first, todo

    def _render_traceback_(self):
        """What IPython shows instead of the traceback."""
        first, todo = self.lines()
        return [f"{_RED}{first}{_PLAIN}", todo]

    def __reduce__(self):
        return type(self), (self.todo,)
