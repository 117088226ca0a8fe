"""The hidden checks: inputs the students never see. Instructor only (the student edition leaves
the whole ``instructor/`` folder out).

The grader (``hwtools/grade``) loads this file from the reference kit it grades against and asks
``hidden_cases(behaviour)`` for each behaviour of ``hwtools/grade/checks/``. The inputs are made
by the same generators as the visible ones but from this folder's own seed, plus a few chosen by
hand, so an answer written for the visible inputs (their values are in the student edition's
answer key) fails here. A behaviour earns its points only if it passes on these too.

Change ``HIDDEN_SEED`` for each offering of the course; the reference answers are recomputed
from the reference solution at every grading, nothing else needs to change.
"""

import numpy as np

HIDDEN_SEED = 0x6F3A_91C2_57D4_0B1E  # instructor-only; pick a new one per offering

# Behaviours with more (or fewer) hidden inputs than visible ones.
COUNTS = {
    "1.1.1/equation-1": 2,  # and the ties chosen by hand below
    "1.2.1/equation-3": 3,
    "1.2.1/one-step": 3,
    "1.3.1/mean-reward": 3,
    "1.3.2/equation-4": 2,
    "1.3.2/records-reward": 2,
    "1.3.2/real-run": 1,
    "1.3.3/converges": 0,  # the handout asks about the notebook's run only
    "2.2.1/values": 4,
    "2.2.1/precision": 2,
    "2.3.1/iterations": 3,
}


def _extra_cases(behaviour_id):
    """Inputs chosen by hand, beyond the generated ones."""
    if behaviour_id == "1.2.1/equation-3":
        # one tiny and one large step next to each other: an h taken from the wrong coordinate shows at once
        return [{"f": {"kind": "coupled", "a": np.array([1.5, -0.7, 2.0]), "b": np.array([0.4, -1.1, 0.3]),
                       "m": np.array([[0.5, -0.2, 0.1], [0.3, 0.8, -0.6], [0.0, 0.7, -0.4]])},
                 "x": np.array([0.3, -1.2, 1.7]), "h": np.array([0.01, 0.9, 0.2])}]
    if behaviour_id == "1.3.1/mean-reward":
        return [{"params": np.array([0.0, 0.0, 0.0, 0.0]), "num_rollouts": 5, "seed": 4242}]
    if behaviour_id == "2.2.1/any-shape":
        return [{"z": np.array([[-800.0, 800.0], [-36.0, 36.0]])}]
    if behaviour_id == "1.1.1/equation-1":
        # ties whose score is exactly 0 in any order of summation, with halves as well as whole numbers
        return [{"params": np.array([[0.5, -1.0, 2.0, 0.25], [1.0, 1.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]]),
                 "obs": np.array([[1.0, 0.5, 0.0, 0.0], [0.5, -0.25, 3.0, 0.25], [0.01, -0.02, 0.03, 0.04]])}]
    return []


def hidden_cases(behaviour):
    """The hidden inputs of one behaviour (a ``hwtools.grade.checks.behaviour.Behaviour``)."""
    count = COUNTS.get(behaviour.id, behaviour.visible_count)
    rng = np.random.default_rng([HIDDEN_SEED, int.from_bytes(behaviour.id.encode(), "little") % (2**63)])
    return [behaviour.make(rng, variant) for variant in range(count)] + _extra_cases(behaviour.id)
