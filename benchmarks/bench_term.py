"""The term's steps timed (docs/instructor.md, "The term, step by step"): each command as an instructor
runs it, from this kit, in turn, with the load average before and after.

Run from the kit's root:  .venv/bin/python benchmarks/bench_term.py [--submissions 30] [--out DIR]

Steps: the facts (``python -m instructor.facts --check``: the same reading as writing them), the release
check, the student edition, the Gradescope bundle (both into ``OUT``), a class run of ``--submissions``
distinct correct zips (``bench_classroom.make_class``) with ``--jobs 2``, and the regrade: the same
command again, nothing changed (every result reused), then after ``.grades-state/`` is deleted (everything
graded again). Canvas and similarity are the canvas branch's (``bench_similarity.py``). The machine is
shared: benchmarks/RESULTS.md gives the numbers measured, dated, with the load.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_classroom import make_class
from hwtools.grade import blocks

KIT = Path(__file__).resolve().parents[1]


def timed(name, args):
    """Run ``python args`` in the kit; print and return its wall seconds, with the CPU seconds of it and
    every process it waited for (the sandboxed runs included: a quiet box's wall time, about) and the load."""
    before, cpu = os.getloadavg()[0], resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=KIT, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        sys.exit(f"{name} failed ({done.returncode}):\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    used = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
    print(f"{name:<22} {seconds:7.1f} s   CPU {used:6.1f} s   load {before:.1f} -> {os.getloadavg()[0]:.1f}", flush=True)
    return seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--submissions", type=int, default=30, help="submissions in the class (default 30)")
    parser.add_argument("--out", help="where the editions and the class go (default: a temporary folder)")
    args = parser.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench-term-"))
    try:
        timed("facts", ["-m", "instructor.facts", "--check"])
        timed("release check", ["-m", "instructor.release", "check"])
        timed("student edition", ["-m", "instructor.release", "student", str(out / "student"), "--force"])
        timed("Gradescope bundle", ["-m", "instructor.release", "gradescope", str(out / "autograder.zip"), "--force"])
        folder = make_class(blocks.load_layout(KIT), out / "class", args.submissions, "term")
        run = ["-m", "hwtools.grade", str(folder), "--gradebook", str(out / "grades.csv"), "--feedback",
               str(out / "feedback"), "--jobs", "2"]
        timed(f"class run ({args.submissions})", run)
        timed("regrade, unchanged", run)
        shutil.rmtree(out / ".grades-state")
        timed("regrade, everything", run)
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
