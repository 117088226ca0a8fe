"""Day one's costs: Run All of each notebook, and the check cell of each TODO.

    .venv/bin/python benchmarks/bench_dayone.py [--rounds N] [--skip-run-all] [--skip-p2] [--skip-checks] [--skip-pytest]
        [--done] [--reuse]

1. **Run All of problem 1** (the instructor's edition, a fresh kernel, as ``nbconvert --execute``
   does): wall clock and CPU seconds (the kernel and everything it ran: the check cells' graders
   and their sandboxes), cell by cell, with the check cells and, side by side in the same run
   (alternating, so that a change of load hits both alike), a copy without them. The
   target is 30 s on a quiet 2-core box (benchmarks/RESULTS.md); on a shared machine the CPU seconds are the better guide
   to what a quiet box gives.
   **Run All of problem 2** the same way, with hwlib's one BLAS thread and, side by side (alternating),
   with ``OPENBLAS_NUM_THREADS`` set to the number of cores (OpenBLAS's own default), cell by cell:
   the notebooks' "about N seconds" are these cell times at a stated load.
2. **One check per TODO** (``hwtools.check_cell.grade_todo``, what ``check("1.2.1")`` runs): wall and
   CPU seconds in the instructor's edition (grading the solutions, hidden inputs included) and in
   a student edition whose TODOs hold the solutions (the answer key, visible checks only: what a
   student who is done waits for). The target is 3 s per TODO on 2 cores.
3. **The untouched student edition's ``pytest``** (``tests/instructor/day_one.py``'s day-one edition, every
   test as the student runs them): seconds and lines printed (it took 13.5 min and printed 3,400
   lines before its failures named their TODO and its browser tests waited for errors they could
   not see).
4. **The done student's path** (``--done``): the student edition with every TODO holding the
   reference solution and JupyterLab's checkpoint beside ``hwlib/cartpole.py``, run with a Python like
   a student's (``day_one.student_python``): its ``pytest`` (seconds, tests), then
   ``python -m hwtools.handin ID --no-report`` and ``python -m hwtools.handin ID`` (seconds; the
   report runs both notebooks). ``hwtools/handin.py`` says the report's time from these runs.

Measured 2026-12-02 on a 2-core Debian box shared by four sessions: the done edition's pytest, 218
tests, 74 s to 2 min 37 s at load 3-6 (94 s at load 3.1-4.8 in this script); hand-in --no-report
11-14 s at load 3-5 (its ten checks); hand-in with the report 1 min 32 s at load 4-5, the report
alone 2 min 18 s at load 3-7.

5. **The loop after 1.3** (``--reuse``): Run All of problem 1 with the learning-rate sweep trained (an empty
   ``HWLIB_CACHE_DIR``) and, next, read back (the folder that run filled: the same code and settings, as after
   an edit of 1.3.3), in turns; the whole Run All and the sweep's cell, and whether every compared output
   (what nbval compares: the cells without ``NBVAL_IGNORE_OUTPUT``) is the same both ways.

The load average of the machine is printed before and after: on a shared machine wall times
grow with it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

KIT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(KIT))
P1 = KIT / "notebooks" / "p1_cartpole_finite_difference.ipynb"
P2 = KIT / "notebooks" / "p2_food_cutting_logistic_regression.ipynb"


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_all(path):
    """(wall seconds including the kernel's start, CPU seconds of the kernel and its children,
    [(cell id, first line, seconds)], the executed notebook) of one Run All in a fresh kernel."""
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(notebook, timeout=1800, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}})
    cells = []
    cpu, started = children_cpu(), time.perf_counter()
    with client.setup_kernel():
        for index, cell in enumerate(notebook.cells):
            if cell.cell_type == "code":
                at = time.perf_counter()
                client.execute_cell(cell, index)
                cells.append((cell.id, cell.source.splitlines()[0][:48] if cell.source else "", time.perf_counter() - at))
    time.sleep(0.5)  # the kernel has exited and been waited for: its CPU is counted
    return time.perf_counter() - started, children_cpu() - cpu, cells, notebook


def without_checks(path, out):
    notebook = json.loads(path.read_text())
    notebook["cells"] = [cell for cell in notebook["cells"]
                         if not (cell["cell_type"] == "code" and "".join(cell["source"]).startswith("check("))]
    out.write_text(json.dumps(notebook))
    return out


def bench_run_all(rounds):
    with tempfile.TemporaryDirectory(prefix="bench-dayone-") as scratch:
        bare = without_checks(P1, Path(scratch) / P1.name)
        shutil.copy2(P1, Path(scratch) / "with_checks.ipynb")
        results = {"with check cells": [], "without": []}
        for _ in range(rounds):
            for name, path in (("with check cells", Path(scratch) / "with_checks.ipynb"), ("without", bare)):
                wall, cpu, cells, _ = run_all(path)
                results[name].append((wall, cpu, cells))
                print(f"  Run All of p1 {name:16s}: {wall:6.1f} s wall, {cpu:6.1f} s CPU", flush=True)
    print_runs("p1", results, slow_cells_of=("with check cells",))


def print_runs(notebook, results, slow_cells_of):
    """The medians of each way's runs; the cells over 0.5 s of the slowest run of the ways named."""
    print(f"\nRun All of {notebook} (median of {len(next(iter(results.values())))})")
    for name, runs in results.items():
        print(f"  {name:16s}: {statistics.median(r[0] for r in runs):6.1f} s wall, "
              f"{statistics.median(r[1] for r in runs):6.1f} s CPU")
        if name in slow_cells_of:
            print(f"  cells of the slowest run {name}, over 0.5 s:")
            for cell_id, first, seconds in max(runs, key=lambda r: r[0])[2]:
                if seconds >= 0.5:
                    print(f"    {cell_id:14s} {seconds:6.1f} s  {first}")


def bench_run_all_p2(rounds):
    """Run All of p2 with hwlib's one BLAS thread, and with OpenBLAS's default (one per core), in turns."""
    cores = str(os.cpu_count() or 1)
    results = {"one BLAS thread": [], f"{cores} BLAS threads": []}
    for _ in range(rounds):
        for name in results:
            previous = os.environ.pop("OPENBLAS_NUM_THREADS", None)
            if name != "one BLAS thread":
                os.environ["OPENBLAS_NUM_THREADS"] = cores  # the kernel inherits it; hwlib leaves a setting alone
            try:
                wall, cpu, cells, _ = run_all(P2)
            finally:
                os.environ.pop("OPENBLAS_NUM_THREADS", None)
                if previous is not None:
                    os.environ["OPENBLAS_NUM_THREADS"] = previous
            results[name].append((wall, cpu, cells))
            print(f"  Run All of p2, {name:16s}: {wall:6.1f} s wall, {cpu:6.1f} s CPU (load {os.getloadavg()[0]:.1f})", flush=True)
    print_runs("p2", results, slow_cells_of=tuple(results))


def compared_outputs(notebook):
    """What nbval compares: each code cell's text outputs, a stream's chunks joined (a kernel may flush one
    print in two), but for the cells marked NBVAL_IGNORE_OUTPUT."""
    cells = []
    for cell in notebook.cells:
        if cell.cell_type != "code" or "NBVAL_IGNORE_OUTPUT" in cell.source:
            continue
        outputs = []
        for output in cell.outputs:
            if output.get("name") and outputs and outputs[-1][0] == output["name"]:
                outputs[-1] = (output["name"], outputs[-1][1] + output["text"], None)
            else:
                outputs.append((output.get("name"), output.get("text"), output.get("data", {}).get("text/plain")))
        cells.append(outputs)
    return cells


def bench_reuse(rounds):
    """Run All of p1, the sweep trained (a new, empty cache folder) then read back (that folder), in turns."""
    previous = os.environ.get("HWLIB_CACHE_DIR")
    results, outputs = {"sweep trained": [], "sweep read back": []}, {}
    try:
        with tempfile.TemporaryDirectory(prefix="bench-dayone-") as scratch:
            copy = Path(scratch) / P1.name
            shutil.copy2(P1, copy)
            for index in range(rounds):
                os.environ["HWLIB_CACHE_DIR"] = str(Path(scratch) / f"cache-{index}")
                for name in results:
                    wall, cpu, cells, notebook = run_all(copy)
                    sweep = next(seconds for _, first, seconds in cells if first.startswith("sweep = "))
                    results[name].append((wall, cpu, cells, sweep))
                    outputs.setdefault(name, compared_outputs(notebook))
                    differ = [index for index, (mine, first) in enumerate(zip(compared_outputs(notebook), outputs["sweep trained"]))
                              if mine != first]
                    print(f"  Run All of p1, {name:16s}: {wall:6.1f} s wall, {cpu:6.1f} s CPU, the sweep's cell {sweep:5.1f} s; "
                          f"outputs {'the same' if not differ else 'DIFFER'} (load {os.getloadavg()[0]:.1f})", flush=True)
                    for index in differ:
                        print(f"    compared cell {index}: {str(compared_outputs(notebook)[index])[:600]}\n"
                              f"      first run's: {str(outputs['sweep trained'][index])[:600]}")
    finally:
        os.environ.pop("HWLIB_CACHE_DIR", None)
        if previous is not None:
            os.environ["HWLIB_CACHE_DIR"] = previous
    print(f"\nthe loop after 1.3 (median of {rounds}):")
    for name, runs in results.items():
        print(f"  {name:16s}: Run All {statistics.median(r[0] for r in runs):6.1f} s wall, "
              f"{statistics.median(r[1] for r in runs):6.1f} s CPU; the sweep's cell {statistics.median(r[3] for r in runs):5.1f} s")
    print(f"  compared outputs the same both ways: {outputs['sweep read back'] == outputs['sweep trained']}")


def bench_checks(rounds):
    """One check per TODO in both editions."""
    from hwtools.check_cell import grade_todo
    from hwtools.grade import checks
    from instructor.release import build_student_edition
    from hwtools.todos import TODO_BY_ID

    with tempfile.TemporaryDirectory(prefix="bench-dayone-") as scratch:
        student = Path(scratch) / "student"
        build_student_edition(KIT, student, keep=frozenset(TODO_BY_ID))
        print(f"\none check per TODO (median of {rounds}): wall / CPU seconds")
        print(f"  {'TODO':6s} " + " ".join(f"{kit:>24s}" for kit in ("instructor", "student (done)")))
        worst = (0.0, None)
        for todo in checks.GRADED_TODOS:
            row = []
            for kit in (KIT, student):
                walls, cpus = [], []
                for _ in range(rounds):
                    cpu, started = children_cpu(), time.perf_counter()
                    grade_todo(todo, kit=kit)
                    walls.append(time.perf_counter() - started)
                    cpus.append(children_cpu() - cpu)
                row.append((statistics.median(walls), statistics.median(cpus)))
            worst = max(worst, (row[-1][0], todo))
            print(f"  {todo:6s} " + " ".join(f"{wall:14.2f} / {cpu:5.2f} s" for wall, cpu in row)
                  + f"  (load {os.getloadavg()[0]:.1f})", flush=True)
        print(f"  the slowest check (student edition): {worst[1]}, {worst[0]:.2f} s")


def bench_untouched_pytest():
    import subprocess

    sys.path.insert(0, str(KIT / "tests" / "instructor"))
    from day_one import day_one_edition, kit_env

    with tempfile.TemporaryDirectory(prefix="bench-dayone-") as scratch:
        kit = day_one_edition(Path(scratch) / "kit")
        started = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider"], cwd=kit, env=kit_env(kit),
                              capture_output=True, text=True)
        seconds = time.perf_counter() - started
    lines = done.stdout.splitlines()
    print(f"\nthe untouched student edition's pytest: {seconds:.0f} s, {len(lines)} lines; {lines[-1].strip('= ')}")


def bench_done_path():
    import subprocess

    sys.path.insert(0, str(KIT / "tests" / "instructor"))
    from day_one import kit_env, student_python
    from hwtools.todos import TODO_BY_ID
    from instructor.release import build_student_edition

    with tempfile.TemporaryDirectory(prefix="bench-dayone-") as scratch:
        kit = Path(scratch) / "kit"
        build_student_edition(KIT, kit, keep=frozenset(TODO_BY_ID))
        (kit / "hwlib" / ".ipynb_checkpoints").mkdir()
        shutil.copyfile(kit / "hwlib" / "cartpole.py", kit / "hwlib" / ".ipynb_checkpoints" / "cartpole-checkpoint.py")
        python = student_python(Path(scratch) / "venv")
        print("\nthe done student's path (a filled student edition, a checkpoint beside cartpole.py):")
        for what, args in (("pytest", ["-m", "pytest", "-q", "-p", "no:cacheprovider"]),
                           ("hand-in --no-report", ["-m", "hwtools.handin", "alovelac", "--no-report"]),
                           ("hand-in with the report", ["-m", "hwtools.handin", "alovelac"])):
            load, started = os.getloadavg()[0], time.perf_counter()
            done = subprocess.run([str(python), *args], cwd=kit, env=kit_env(kit), capture_output=True, text=True)
            seconds = time.perf_counter() - started
            last = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr.strip()[-200:]
            print(f"  {what:24s} {seconds:6.1f} s (load {load:.1f} -> {os.getloadavg()[0]:.1f}; exit {done.returncode}): "
                  f"{last.strip('= ')}", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--skip-run-all", action="store_true")
    parser.add_argument("--skip-p2", action="store_true")
    parser.add_argument("--skip-checks", action="store_true")
    parser.add_argument("--skip-pytest", action="store_true")
    parser.add_argument("--done", action="store_true", help="only the done student's path: pytest and hand-in")
    parser.add_argument("--reuse", action="store_true", help="only the loop after 1.3: Run All of p1, sweep trained vs read back")
    args = parser.parse_args()
    os.environ.setdefault("MPLBACKEND", "Agg")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    if args.reuse:
        bench_reuse(args.rounds)
        print(f"\nload average {os.getloadavg()[0]:.1f} at the end")
        return
    if args.done:
        bench_done_path()
        print(f"\nload average {os.getloadavg()[0]:.1f} at the end")
        return
    if not args.skip_checks:
        bench_checks(args.rounds)
    if not args.skip_run_all:
        bench_run_all(args.rounds)
    if not args.skip_p2:
        bench_run_all_p2(args.rounds)
    if not args.skip_pytest:
        bench_untouched_pytest()
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
