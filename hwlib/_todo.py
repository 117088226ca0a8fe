""""Not done yet": the error a TODO's starting code raises until the student writes it.

Every TODO stub in the student edition is its hint as a comment and ``raise TodoNotDone("1.1.1")``;
the module-level 1.3.3 is ``LEARNING_RATE = None``, and whatever reads it raises
``TodoNotDone("1.3.3")``. In a notebook IPython shows the two lines of ``_render_traceback_``
instead of a traceback, so a cell that needs an unwritten TODO says which one, at the top of its
output; in pytest the same two lines are the error's message.
"""

from __future__ import annotations

# Where each TODO's code goes: (what to write, the file). The grader's own table
# (hwtools/todos.py) says the same; tests/test_todo.py keeps the two in step.
TODO_CODE = {
    "1.1.1": ("CartPoleLinearPolicy.__call__", "hwlib/cartpole.py"),
    "1.1.2": ("the `tried` cell", "notebooks/p1_cartpole_finite_difference.ipynb"),
    "1.2.1": ("scalar_finite_diff", "hwlib/finite_diff.py"),
    "1.3.1": ("eval_params", "hwlib/policy_search.py"),
    "1.3.2": ("the loop of train_cartpole_policy", "hwlib/policy_search.py"),
    "1.3.3": ("LEARNING_RATE", "hwlib/settings.py"),
    "2.1.1": ("log_likelihood_gradient", "hwlib/logreg.py"),
    "2.2.1": ("sigmoid", "hwlib/logreg.py"),
    "2.2.2": ("TwoClassLogisticRegressionClassifier.predict_prob", "hwlib/logreg.py"),
    "2.2.3": ("TwoClassLogisticRegressionClassifier.gradient_ascent_step", "hwlib/logreg.py"),
    "2.3.1": ("the loop over classes in MultiClassLogisticRegressionClassifier.fit", "hwlib/logreg.py"),
    "2.3.2": ("the training cell", "notebooks/p2_food_cutting_logistic_regression.ipynb"),
}
_RED, _PLAIN = "\x1b[1;31m", "\x1b[0m"


class TodoNotDone(NotImplementedError):
    """Raised by the starting code of TODO ``todo`` (e.g. ``"1.1.1"``): the student has not written it yet."""

    def __init__(self, todo):
        self.todo = str(todo)
        super().__init__("\n".join(self.lines()))

    def lines(self):
        """Two lines: which TODO and where its code goes, then what to do."""
        what, where = TODO_CODE.get(self.todo, (None, None))
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
