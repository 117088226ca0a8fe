"""The similarity report's benchmark: recall of planted copies, flags among independent solutions,
and the time of ``python -m hwtools.grade CLASS --similarity OUT`` on a class of 150.

Run from the kit's root:  .venv/bin/python benchmarks/bench_similarity.py [--students 150] [--copies 8]
                          [--seeds 1 2 3]

Each seed makes a class (``tests/grader/similarity_class.py``: every student writes each TODO a way
of their own; ``--copies`` copiers each take another's whole ``hwlib/`` and disguise it by renamed
variables, reordered lines, added comments or one changed constant, in turn), zipped as students
hand in, and times the command in a fresh process (wall and CPU seconds, peak memory). Then:

* recall: the share of the planted pairs among each TODO's 10 best pairs (1.3.3, one constant,
  left out), the worst TODO and over all TODOs, of the pairs a TODO can show: a pair one of whose
  blocks is only the handout's equations (``similarity_class.handout_only``) is not counted there,
  and how many were left out is printed;
* flags among independent students: pair-TODOs flagged that are no planted pair, of all pairs;
* the kit's natural solutions (``tests/grader/natural_solutions/``, each a submission of its own,
  ``_crlf`` twins left out): pairs of one TODO's solutions flagged, of all such pairs.

The machine is shared while the kit is being built: the load average is printed with the numbers;
benchmarks/RESULTS.md gives the ones measured, dated.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

KIT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(KIT / "tests" / "grader"))

import similarity_class  # noqa: E402
from hwtools.grade import blocks  # noqa: E402
from hwtools.grade.instructor import similarity  # noqa: E402


def zipped(folder, out):
    """Each submission of ``folder`` as ``out/<student>.zip`` (its kit one folder down, as students zip)."""
    out.mkdir(parents=True)
    for student in sorted(path.name for path in folder.iterdir()):
        with zipfile.ZipFile(out / f"{student}.zip", "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for path in sorted((folder / student).rglob("*.py")):
                archive.write(path, f"hw1/{path.relative_to(folder / student).as_posix()}")
    return out


def timed_command(submissions, out):
    """(wall s, CPU s, peak MiB) of the command in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    subprocess.run([sys.executable, "-m", "hwtools.grade", str(submissions), "--similarity", str(out)], cwd=KIT,
                   check=True, stdout=subprocess.DEVNULL)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return wall, cpu, after.ru_maxrss / 1024


def natural_flags(layout, folder):
    pairs = similarity_class.natural_class(layout, folder)
    report = similarity.similarity(folder, layout)
    return sum(pair.flagged for found in report.pairs.values() for pair in found), pairs


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--students", type=int, default=150)
    parser.add_argument("--copies", type=int, default=8)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    args = parser.parse_args()
    layout = blocks.load_layout(KIT)
    print(f"load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} CPUs; a class of {args.students}, "
          f"{args.copies} copiers", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-similarity-") as scratch:
        scratch = Path(scratch)
        flagged, pairs = natural_flags(layout, scratch / "natural")
        print(f"natural solutions: {flagged} of {pairs} pairs flagged ({flagged / pairs:.1%})", flush=True)
        for seed in args.seeds:
            planted = similarity_class.make_class(layout, scratch / f"class{seed}", args.students, args.copies, seed)
            submissions = zipped(scratch / f"class{seed}", scratch / f"zips{seed}")
            wall, cpu, peak = timed_command(submissions, scratch / f"out{seed}")
            report = similarity.similarity(submissions, layout)
            recall = {todo: found for todo, found in similarity_class.recall(report, planted, layout).items()
                      if todo != "1.3.3"}
            left_out = sum(len(pairs) for todo, pairs in similarity_class.handout_only(report, planted, layout).items()
                           if todo != "1.3.3")
            independent = sum(pair.flagged and pair.students not in planted
                              for found in report.pairs.values() for pair in found)
            all_pairs = args.students * (args.students - 1) // 2 * len(recall)
            worst = min(recall, key=recall.get)
            print(f"seed {seed}: {wall:.1f} s wall, {cpu:.1f} s CPU, {peak:.0f} MiB peak; recall in the top 10: "
                  f"{sum(recall.values()) / len(recall):.3f} over the TODOs, worst {recall[worst]:.3f} ({worst}), "
                  f"{left_out} of {len(planted) * len(recall)} planted pair-TODOs only the handout's; "
                  f"independent pair-TODOs flagged {independent} of {all_pairs} ({independent / all_pairs:.3%}); "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)


if __name__ == "__main__":
    main()
