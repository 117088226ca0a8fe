"""Grading benchmark: seconds per submission, in the bubblewrap sandbox and without it, 1 and 2 jobs.

Run from the kit's root:  .venv/bin/python benchmarks/bench_grading.py  [--submissions N] [--quick] [--baseline REF]

Each submission is the reference solution with a comment of its own in every block, so that no
TODO's kit matches one the grader has run before: every TODO's worker runs, as for a real class
where no two students write the same code. The first grading of a Grader also computes the
reference's answers (once per grader, reused for every later submission); it is timed apart.

``--baseline REF`` measures the grader of git revision REF (for example ``main``) side by side:
each setting runs the baseline's grader (exported from git into a temporary folder, in a
subprocess of the same Python) and then this kit's, and the table gives both and the ratio.

Numbers depend on the machine and on what else runs on it; the README gives the ones measured
on the kit's 2-core machine, with the load at the time.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

SETTINGS = (("auto", 1), ("none", 1), ("auto", 2), ("none", 2))


def fresh_submissions(blocks, layout, folder, count, tag):
    """``count`` kits: every block holds the reference's code plus a comment unique to the kit."""
    reference = layout.reference_bodies()
    kits = []
    for number in range(count):
        bodies = {todo: ["\n".join(body) + f"\n# submission {tag}-{number}" for body in found]
                  for todo, found in reference.items()}
        kits.append(blocks.write_submission(layout, Path(folder) / f"{tag}-{number}", bodies))
    return kits


def bench(kit, isolation, jobs, count, folder):
    """(isolated, seconds of the first grading, [seconds of each later one]) with the grader of ``kit``."""
    from hwtools.grade import Grader, blocks  # noqa: PLC0415 - the hwtools of the kit measured (PYTHONPATH)

    grader = Grader(kit, isolation=isolation, jobs=jobs)
    kits = fresh_submissions(blocks, blocks.load_layout(kit), folder, count + 1, f"{isolation}-{jobs}")
    start = time.perf_counter()
    first = grader.grade(kits[0])
    setup = time.perf_counter() - start
    assert first["total"]["auto_earned"] == 39, first["total"]
    times = []
    for submission in kits[1:]:
        start = time.perf_counter()
        result = grader.grade(submission)
        times.append(time.perf_counter() - start)
        assert result["total"]["auto_earned"] == 39, result["total"]
    if hasattr(grader, "close"):
        grader.close()
    return grader.sandbox.isolated, setup, times


def exported(ref, kit, folder):
    """The files of git revision ``ref`` of ``kit``, in ``folder`` (the course data is not needed)."""
    archive = Path(folder) / "baseline.tar"
    subprocess.run(["git", "-C", str(kit), "archive", "--format=tar", "-o", str(archive), ref], check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(Path(folder) / "baseline", filter="data")
    return Path(folder) / "baseline"


def measure_elsewhere(kit, isolation, jobs, count):
    """``bench`` of the kit at ``kit`` (its own hwtools first on the path), in a subprocess."""
    env = dict(os.environ, PYTHONPATH=str(kit))
    output = subprocess.run([sys.executable, __file__, "--one", str(kit), isolation, str(jobs), str(count)],
                            env=env, cwd=kit, capture_output=True, text=True, check=True).stdout
    return json.loads(output.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--submissions", type=int, default=3, help="timed submissions per setting (default 3)")
    parser.add_argument("--quick", action="store_true", help="one submission per setting")
    parser.add_argument("--baseline", metavar="REF", help="also measure the grader of this git revision, side by side")
    parser.add_argument("--one", nargs=4, metavar=("KIT", "ISOLATION", "JOBS", "COUNT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        kit, isolation, jobs, count = args.one
        with tempfile.TemporaryDirectory(prefix="bench-grading-") as folder:
            isolated, setup, times = bench(Path(kit), isolation, int(jobs), int(count), folder)
        print(json.dumps({"isolated": isolated, "setup": setup, "times": times}))
        return
    kit = Path(__file__).resolve().parents[1]
    count = 1 if args.quick else args.submissions
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPU(s), load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (a shared machine is noisy)")
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as folder:
        baseline = exported(args.baseline, kit, folder) if args.baseline else None
        header = f"{'isolation':<10} {'jobs':>4}  {'first (+reference)':>18}  {'per submission':>16}  {'min':>6}  {'max':>6}"
        print(header + (f"  {'baseline ' + args.baseline:>18}  {'ratio':>6}" if baseline else ""))
        for isolation, jobs in SETTINGS:
            old = measure_elsewhere(baseline, isolation, jobs, count) if baseline else None
            now = measure_elsewhere(kit, isolation, jobs, count)
            name = "bwrap" if now["isolated"] else "none"
            mean = statistics.mean(now["times"])
            line = (f"{name:<10} {jobs:>4}  {now['setup']:>17.1f}s  {mean:>15.2f}s  {min(now['times']):>5.2f}s  "
                    f"{max(now['times']):>5.2f}s")
            if old:
                old_mean = statistics.mean(old["times"])
                line += f"  {old_mean:>17.2f}s  {mean / old_mean:>5.2f}x"
            print(line, flush=True)


if __name__ == "__main__":
    main()
