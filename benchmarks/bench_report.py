"""Report benchmark: the seconds of ``python -m hwtools.report OUT_DIR --name X``, and of its parts, for this kit
and (side by side, alternating, on the same machine) another checkout of it.

Run from the kit's root:
    .venv/bin/python benchmarks/bench_report.py [--before DIR] [--rounds N]

``--before DIR``: a folder holding another version of the kit (for example
``git worktree add /tmp/kit-before COMMIT``); its ``hwtools`` and ``hwlib`` are run with this
environment's Python. Each round runs both, one after the other, so that both see the same load.

| column     | what is timed                                                                         |
|------------|---------------------------------------------------------------------------------------|
| total      | the whole command, wall clock, Python start included                                 |
| notebooks  | until both notebooks have run in their kernels (the report's "figures:" line)         |
| the rest   | figures, answers.md/.tex, the HTML pages typeset in Chromium, answers.pdf            |

Most of the time is the notebooks (the report computes nothing they compute); "the rest" is what the
report itself does. The ratio is this kit's median over the other's. Timings are wall-clock on whatever
the machine is doing: on a shared machine, compare the two versions within one run only.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

KIT = Path(__file__).resolve().parent.parent
PROGRESS = re.compile(r"^\[\s*([\d.]+) s\] (.*)$", flags=re.MULTILINE)


def run_report(kit, out_dir):
    """One run of the command from ``kit``: {total, notebooks, rest} in seconds."""
    env = dict(os.environ, PYTHONPATH=str(kit), MPLBACKEND="Agg")
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "hwtools.report", str(out_dir), "--name", "Bench Mark / bmark"],
                          cwd=tempfile.gettempdir(), env=env, capture_output=True, text=True)
    total = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"the report from {kit} failed:\n{done.stdout}\n{done.stderr}")
    steps = [(float(seconds), message) for seconds, message in PROGRESS.findall(done.stdout)]
    notebooks = next(seconds for seconds, message in steps if message.startswith("figures:"))
    return {"total": total, "notebooks": notebooks, "rest": steps[-1][0] - notebooks}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--before", type=Path, help="another checkout of the kit, timed side by side")
    parser.add_argument("--rounds", type=int, default=2, help="runs of each version (default 2)")
    args = parser.parse_args(argv)
    kits = {"this kit": KIT}
    if args.before is not None:
        kits = {"before": args.before.resolve(), **kits}
    times = {label: [] for label in kits}
    with tempfile.TemporaryDirectory(prefix="bench-report-") as tmp:
        for round_number in range(1, args.rounds + 1):
            for label, kit in kits.items():
                result = run_report(kit, Path(tmp) / f"{label.replace(' ', '-')}-{round_number}")
                times[label].append(result)
                print(f"round {round_number}, {label:8}: total {result['total']:6.1f} s, notebooks "
                      f"{result['notebooks']:6.1f} s, the rest {result['rest']:5.1f} s", flush=True)
    medians = {label: {part: statistics.median(run[part] for run in runs) for part in runs[0]}
               for label, runs in times.items()}
    for label, median in medians.items():
        print(f"median, {label:8}: total {median['total']:6.1f} s, notebooks {median['notebooks']:6.1f} s, "
              f"the rest {median['rest']:5.1f} s")
    if "before" in medians:
        after, before = medians["this kit"], medians["before"]
        print("this kit / before: " + ", ".join(f"{part} {after[part] / before[part]:.2f}x" for part in after))


if __name__ == "__main__":
    main()
