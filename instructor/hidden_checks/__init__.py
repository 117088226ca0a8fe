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

import hashlib
import hmac

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


def _extra_cases(behaviour_id, rng):
    """Inputs chosen by hand, beyond the generated ones: their structure is fixed, their numbers drawn."""
    if behaviour_id == "1.2.1/equation-3":
        # one tiny and one large step next to each other: an h taken from the wrong coordinate shows at once
        return [{"f": {"kind": "coupled", "a": rng.uniform(-2, 2, 3).round(1), "b": rng.uniform(-1.2, 1.2, 3).round(1),
                       "m": rng.uniform(-0.8, 0.8, (3, 3)).round(1)},
                 "x": rng.uniform(-1.5, 1.5, 3).round(1), "h": np.array([0.01, float(rng.uniform(0.6, 0.9)), 0.2])}]
    if behaviour_id == "1.3.1/mean-reward":
        return [{"params": np.array([0.0, 0.0, 0.0, 0.0]), "num_rollouts": 5, "seed": int(rng.integers(1000, 10_000))}]
    if behaviour_id == "2.2.1/any-shape":
        far, mid = float(rng.uniform(750, 1000)), float(rng.uniform(30, 40))
        return [{"z": np.array([[-far, far], [-mid, mid]])}]
    if behaviour_id == "1.1.1/equation-1":
        # ties whose score is exactly 0 in any order of summation, with halves as well as whole numbers
        a, b = float(rng.integers(1, 4)) / 2, float(rng.integers(1, 4))
        return [{"params": np.array([[a, -1.0, 2.0, 0.25], [1.0, 1.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]]),
                 "obs": np.array([[1.0, a, 0.0, 0.0], [b / 2, -b / 4, 3.0, b / 4], rng.uniform(-0.05, 0.05, 4)])}]
    return []


def hidden_cases(behaviour, draw=""):
    """The hidden inputs of one behaviour (a ``hwtools.grade.checks.behaviour.Behaviour``), drawn from
    HMAC-SHA256(HIDDEN_SEED, behaviour id + ``draw``); the grader passes as ``draw`` the secret of one
    grading (random, drawn afresh for each grading, kept with the instructor's result), so no earlier
    grading's inputs tell anything of a later one's, and a regrade with the stored secret gets the same."""
    count = COUNTS.get(behaviour.id, behaviour.visible_count)
    key = hmac.new(str(HIDDEN_SEED).encode(), f"{behaviour.id}\0{draw}".encode(), hashlib.sha256).digest()
    rng = np.random.default_rng(int.from_bytes(key, "little"))
    return [behaviour.make(rng, variant) for variant in range(count)] + _extra_cases(behaviour.id, rng)
