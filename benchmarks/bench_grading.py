"""Grading benchmark: seconds per submission, in the bubblewrap sandbox and without it, 1 and 2 jobs.

Run from the kit's root:  .venv/bin/python benchmarks/bench_grading.py  [--submissions N] [--quick]

Each submission is the reference solution with a comment of its own in every block, so that no
TODO's kit matches one the grader has run before: every TODO's worker runs, as for a real class
where no two students write the same code. The first grading of a Grader also computes the
reference's answers (once per grader, reused for every later submission); it is timed apart.

Numbers depend on the machine and on what else runs on it; the README gives the ones measured
on the kit's 2-core machine, with the load at the time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from hwtools.grade import Grader, blocks

KIT = Path(__file__).resolve().parents[1]


def fresh_submissions(layout, folder, count, tag):
    """``count`` kits: every block holds the reference's code plus a comment unique to the kit."""
    reference = layout.reference_bodies()
    kits = []
    for number in range(count):
        bodies = {todo: ["\n".join(body) + f"\n# submission {tag}-{number}" for body in found]
                  for todo, found in reference.items()}
        kits.append(blocks.write_submission(layout, Path(folder) / f"{tag}-{number}", bodies))
    return kits


def bench(isolation, jobs, count, layout, folder):
    grader = Grader(KIT, isolation=isolation, jobs=jobs)
    kits = fresh_submissions(layout, folder, count + 1, f"{isolation}-{jobs}")
    start = time.perf_counter()
    first = grader.grade(kits[0])
    setup = time.perf_counter() - start
    assert first["total"]["auto_earned"] == 39, first["total"]
    times = []
    for kit in kits[1:]:
        start = time.perf_counter()
        result = grader.grade(kit)
        times.append(time.perf_counter() - start)
        assert result["total"]["auto_earned"] == 39, result["total"]
    return grader.sandbox, setup, times


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--submissions", type=int, default=3, help="timed submissions per setting (default 3)")
    parser.add_argument("--quick", action="store_true", help="one submission per setting")
    args = parser.parse_args()
    count = 1 if args.quick else args.submissions
    layout = blocks.load_layout(KIT)
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPU(s), load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (a shared machine is noisy)")
    print(f"{'isolation':<10} {'jobs':>4}  {'first (+reference)':>18}  {'per submission':>16}  {'min':>6}  {'max':>6}")
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as folder:
        for isolation in ("auto", "none"):
            for jobs in (1, 2):
                box, setup, times = bench(isolation, jobs, count, layout, folder)
                name = "bwrap" if box.isolated else "none"
                print(f"{name:<10} {jobs:>4}  {setup:>17.1f}s  {statistics.mean(times):>15.1f}s  "
                      f"{min(times):>5.1f}s  {max(times):>5.1f}s")


if __name__ == "__main__":
    main()
