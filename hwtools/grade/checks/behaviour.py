"""What one graded behaviour of a TODO is: ``Behaviour``, one row of the checks' table.

Its points are the TODO table's (``Todo.checks`` in ``hwlib/machinery/todos.py``).

A behaviour is one thing the handout asks, described in words, worth some points, tried on
visible inputs (made by ``make`` from the public seed: students see them, and the student
edition's answer key holds the reference's values on them) and on hidden ones (made by the
same ``make`` from the instructor's seed, ``instructor/hidden_checks``). In the worker, the
``probe`` of that name (``in_sandbox/probes.py``) calls the student's code on each input; on the
trusted side ``judge`` gives each answer its ``verdicts.Verdict``. Standard library and numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwtools.todos import TODO_BY_ID

PUBLIC_SEED = 20_240_131  # the visible inputs' seed: students may know it
MOST_KEPT = 0.3  # of a TODO's points, the most it keeps while one of its value checks fails on any input


@dataclass(frozen=True)
class Behaviour:
    """One graded behaviour of a TODO; it earns its points only when every input, visible and
    hidden, passes."""

    todo: str
    key: str
    short: str  # what is checked in one line: the first lines of a failure say it (``feedback.first_lines``)
    description: str
    probe: str  # the probe the worker runs on each input (in_sandbox/probes.py)
    make: object  # make(rng, variant) -> the arguments of one case
    judge: object  # judge(args, result, expected_values, services) -> Verdict
    visible_count: int = 2
    services: object = None  # services(args, result) -> [(probe, args)]: reference runs the judge needs
    exact: bool = False  # judged against the reference's values on the same input
    judged_on: str = ""  # the key of another behaviour of the TODO whose cases this one judges (it has none of its own)
    value: bool = False  # checks the TODO's value: while it fails on any input, the TODO keeps MOST_KEPT at most
    # breaks_callers(result) -> what of an answer breaks the code that calls it (the TODOs that do, blame.py),
    # in words ("returns a list where ..."), or "": a note, never a verdict
    breaks_callers: object = None

    @property
    def points(self):
        """Its points: the TODO table's (``Todo.checks``), written once."""
        return TODO_BY_ID[self.todo].check_points[self.key]

    @property
    def id(self):
        return f"{self.todo}/{self.key}"

    def visible_cases(self):
        rng = np.random.default_rng([PUBLIC_SEED, int.from_bytes(self.id.encode(), "little") % (2**63)])
        return [self.make(rng, variant) for variant in range(self.visible_count)]
