"""The visible checks' inputs, rebuilt in your own kernel: ``visible_case("1.2.1/equation-3/v0")``.

A failing visible check prints one line of Python that gives you its input, for example::

    from hwtools.cases import visible_case; f, x, h = visible_case("1.2.1/equation-3/v0")  # then scalar_finite_diff(f, x, h)

Run it in the notebook (or any Python in the kit) and call your function on what it returns: you
get the value the check saw. The inputs are made from the public seed of
``hwtools/grade/checks/``, exactly as the grader makes them; classifiers come from your own
``hwlib/logreg.py``. Hidden inputs cannot be rebuilt here (they are not in the kit).
"""

from __future__ import annotations

from hwtools.grade import checks
from hwtools.grade.in_sandbox import probes

def _case(case_id):
    todo, _, number = str(case_id).partition("/")
    found = [(behaviour, args) for cid, behaviour, args in checks.case_set(todo).visible
             if cid == case_id] if todo in checks.BEHAVIOURS_BY_TODO else []
    if not found or not number:
        raise ValueError(f"{case_id!r} is not a visible check's input; they are named like '1.2.1/equation-3/v0' "
                         "(the failing check prints the line that rebuilds its input)")
    return found[0]


def visible_case(case_id):
    """The input of visible case ``case_id`` ("TODO/check/vN") as your function gets it (see the
    module docstring): a tuple, unpacked as the check's printed line shows."""
    behaviour, args = _case(case_id)
    probe = behaviour.probe
    if probe == "policy_choices":
        return probes.policy_inputs(args)
    if probe == "finite_diff":
        return probes.fd_inputs(args)
    if probe == "eval_params":
        return probes.eval_inputs(args)
    if probe == "train_known":
        return probes.train_inputs(args), probes.training_objective(args["objective"])
    if probe == "train_real":
        return probes.train_inputs(args)
    if probe == "sigmoid":
        return probes.sigmoid_inputs(args)[0]
    if probe == "ll_gradient":
        return probes.ll_gradient_inputs(args)
    if probe in ("predict_prob", "gradient_step", "one_vs_rest"):
        from hwlib import logreg  # noqa: PLC0415 - your kit's classifiers, in your kernel

        return (probes.classifier_inputs if probe != "one_vs_rest" else probes.one_vs_rest_inputs)(args, logreg)
    raise ValueError(f"{case_id!r}: the input of this check is a setting of hwlib/settings.py, nothing to rebuild")
