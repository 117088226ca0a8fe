"""Grading benchmark: seconds per submission in bubblewrap, in the user fallback and without a sandbox.

Run from the kit's root:  .venv/bin/python benchmarks/bench_grading.py  [--submissions N] [--quick] [--baseline REF]
                          [--isolation bwrap user none] [--jobs 1 2]

Each submission is the reference solution with a comment of its own in every block, so that no
TODO's kit matches one the grader has run before: every TODO's worker runs, as for a real class
where no two students write the same code. The first grading of a Grader also computes the
reference's answers (once per grader, reused for every later submission); it is timed apart.

``--baseline REF`` measures the grader of git revision REF (for example ``09db243``, the grader
before the reference server) side by side: for each setting, the baseline's grader (exported from
git into a temporary folder) and this kit's each run in a subprocess of the same Python, both
warmed up by a first grading, and then grade fresh submissions in turns (baseline, this kit,
baseline, ...), so that a change of load on a shared machine weighs on both; the table gives both
medians and their ratio, and, as root, the median CPU seconds of each side's grading (every process
of it, in a cgroup v1 ``cpuacct`` group: a loaded machine stretches wall time far more than CPU
time, and the grader of a baseline with one turn machine-wide waits for other graders' runs). A baseline without the user fallback (09db243 has none) grades the
``user`` setting in bubblewrap, its only sandbox: the ratio is then the fallback's cost against
that grader's isolated time (the bound of issue 17.8).

``user`` (the fallback of containers without namespaces) needs root: the pool's users are
created as ``setup.sh`` creates them, a Python they can run is made from the system's Python with
real copies of this one's packages (``user_sandbox.runnable_python``), and the reference is a
copy in a folder only root may enter (the grader refuses one the pool's users can read).

``--gradescope`` grades fresh submissions as Gradescope's default container runs them (as root:
cgroup v1 ``cpu`` and ``memory`` hierarchies): each one is a new ``/autograder`` folder (the
reference and hidden checks in ``source/``, the submission, ``results/``) graded by
``gradescope_autograder`` in a process started inside a control group of 0.5 CPU
(``cpu.cfs_quota_us`` 50,000 of every 100,000) and 768 MiB of memory (``memory.limit_in_bytes``,
which counts every process of the grading, its sandboxed runs and reference servers included, and
the page cache it brings in); the seconds from start to results.json, the group's peak
(``memory.max_usage_in_bytes``) and the CPU seconds it used (a cpuacct group), which on a loaded
machine say what a quiet half CPU would take.

``--bound SECONDS`` measures what one submission can cost: every TODO an endless loop, graded with
that time limit (by this kit, and by the baseline's when given), after the reference's answers.
The kit's stated bound is ``BUDGET_FACTOR`` x the limit of wall clock for all of a submission's runs.

Numbers depend on the machine and on what else runs on it; benchmarks/RESULTS.md gives the ones measured
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

from hwlib.machinery.todos import AUTO_POINTS


def fresh_submissions(write_submission, layout, folder, count, tag):
    """``count`` kits: every block holds the reference's code plus a comment unique to the kit."""
    reference = layout.reference_bodies()
    kits = []
    for number in range(count):
        bodies = {todo: ["\n".join(body) + f"\n# submission {tag}-{number}" for body in found]
                  for todo, found in reference.items()}
        kits.append(write_submission(layout, Path(folder) / f"{tag}-{number}", bodies))
    return kits


def exported(ref, kit, folder):
    """The files of git revision ``ref`` of ``kit``, in ``folder`` (the course data is not needed)."""
    archive = Path(folder) / "baseline.tar"
    subprocess.run(["git", "-C", str(kit), "archive", "--format=tar", "-o", str(archive), ref], check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(Path(folder) / "baseline", filter="data")
    return Path(folder) / "baseline"


CPUACCT = Path("/sys/fs/cgroup/cpuacct")  # cgroup v1: the CPU time of every process of a group, as root


class Side:
    """A grader of the kit at ``kit`` (its own hwtools first on the path) in a subprocess, warmed
    up; ``grade()`` grades one fresh submission there and returns the seconds it took, and
    ``cpu`` the CPU seconds every process of that grading used (its sandboxed runs and reference
    servers included; None where no cpuacct group can be made): on a shared machine the load
    stretches the seconds, far less the CPU."""

    def __init__(self, kit, isolation, jobs, python=""):
        import uuid  # noqa: PLC0415

        env = dict(os.environ, PYTHONPATH=str(kit))
        command = [sys.executable, __file__, "--serve", str(kit), isolation, str(jobs), python]
        self.group, self.cpu = CPUACCT / f"hwgrade-bench-{uuid.uuid4().hex[:8]}", None
        try:
            self.group.mkdir()
            command = ["/bin/sh", "-c", 'echo $$ > "$1"; shift; exec "$@"', "join", str(self.group / "cgroup.procs"),
                       *command]
        except OSError:
            self.group = None
        self.process = subprocess.Popen(command, env=env, cwd=kit, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.ready = json.loads(self.process.stdout.readline())

    def _usage(self):
        return int((self.group / "cpuacct.usage").read_text()) / 1e9 if self.group else None

    def grade(self):
        before = self._usage()
        self.process.stdin.write("grade\n")
        self.process.stdin.flush()
        seconds = json.loads(self.process.stdout.readline())["seconds"]
        self.cpu = None if before is None else self._usage() - before
        return seconds

    def close(self):
        self.process.stdin.close()
        self.process.wait()
        if self.group:
            self.group.rmdir()


def serve(kit, isolation, jobs, python):
    """The subprocess of a Side: one warm-up grading, then one fresh submission per line on stdin.
    A grader that has no ``isolation="user"`` (before the fallback) grades in bubblewrap."""
    from hwtools.grade import Grader, blocks  # noqa: PLC0415 - the hwtools of the kit measured (PYTHONPATH)

    write_submission = getattr(blocks, "write_submission", None)  # a baseline's grader, before kits.py
    if write_submission is None:
        from hwtools.grade.kits import write_submission  # noqa: PLC0415

    reference = private_reference(kit) if isolation == "user" else kit
    try:
        grader = Grader(reference, isolation=isolation, jobs=jobs, python=python or None)
    except ValueError:  # no such isolation in this grader: its only sandbox
        grader = Grader(kit, isolation="bwrap", jobs=jobs)
    layout = blocks.load_layout(kit)
    kind = getattr(grader.sandbox, "kind", "bwrap" if grader.sandbox.isolated else "none")
    if getattr(grader, "pool", None) is not None:
        grader.pool.idle = 3600.0  # its reference servers stay up while the other side grades, as in a class graded back to back
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as folder:
        number = 0
        start = time.perf_counter()
        result = grader.grade(fresh_submissions(write_submission, layout, folder, 1, f"warm-{number}")[0])
        assert result["total"]["auto_earned"] == result["total"]["auto_possible"], result["total"]
        print(json.dumps({"kind": kind, "setup": time.perf_counter() - start}), flush=True)
        for _ in sys.stdin:
            number += 1
            kit_dir = fresh_submissions(write_submission, layout, folder, 1, f"next-{number}")[0]
            start = time.perf_counter()
            result = grader.grade(kit_dir)
            seconds = time.perf_counter() - start
            assert result["total"]["auto_earned"] == result["total"]["auto_possible"], result["total"]
            print(json.dumps({"seconds": seconds}), flush=True)
    if hasattr(grader, "close"):
        grader.close()


def private_reference(kit):
    """A copy of the reference (``hwlib/`` and the hidden checks) in a folder only root may enter."""
    import shutil  # noqa: PLC0415

    folder = Path(tempfile.mkdtemp(prefix="bench-reference-"))  # mode 0700
    for part in ("hwlib", "instructor/hidden_checks"):
        if (Path(kit) / part).is_dir():
            shutil.copytree(Path(kit) / part, folder / part, ignore=shutil.ignore_patterns("__pycache__"))
    return folder


ENDLESS = """
import json, sys, tempfile, time
from pathlib import Path
from hwtools.grade import Grader, blocks, checks
write_submission = getattr(blocks, "write_submission", None)  # a baseline's grader, before kits.py
if write_submission is None:
    from hwtools.grade.kits import write_submission
kit = Path(sys.argv[1])
with tempfile.TemporaryDirectory() as folder, Grader(kit, time_limit=float(sys.argv[2]), jobs=int(sys.argv[3])) as grader:
    grader.grade(kit, todos=["2.2.1"])  # the reference's servers and answers: once per grader, not the submission's
    loops = write_submission(blocks.load_layout(kit), Path(folder) / "loops",
                             {todo: "while True:\\n    pass" for todo in checks.GRADED_TODOS})
    started = time.monotonic()
    result = grader.grade(loops)
    print(json.dumps({"seconds": time.monotonic() - started,
                      "ran": sum(not any("budget" in note for note in entry["notes"]) for entry in result["todos"]
                                 if entry["id"] in checks.GRADED_TODOS)}))
"""


def bound(kit, baseline, time_limit, jobs):
    """Seconds to grade a submission whose every TODO loops for ever, by this kit and the baseline."""
    for name, where in (("this kit", kit), ("baseline", baseline)):
        if where is None:
            continue
        out = subprocess.run([sys.executable, "-c", ENDLESS, str(where), str(time_limit), str(jobs)], cwd=where,
                             env=dict(os.environ, PYTHONPATH=str(where)), capture_output=True, text=True, check=True)
        measured = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"endless loop in every TODO, --time-limit {time_limit:g}, --jobs {jobs}: {name} {measured['seconds']:.1f} s "
              f"({measured['ran']} of 10 runs ran)", flush=True)


GRADESCOPE_CPU, GRADESCOPE_MEMORY = 0.5, 768 * 2**20  # Gradescope's default container (its autograder docs)


AUTOGRADE = ("import sys; from hwtools.grade.instructor.gradescope_autograder import run; "
             "from hwtools.grade.sandbox import limit_own_memory; limit_own_memory(); "
             "run(sys.argv[1], isolation=sys.argv[2], python=sys.argv[3] or None)")


def gradescope(kit, count, isolation, python):
    """Grade ``count`` fresh submissions, each as Gradescope's default container would: seconds and peak MiB."""
    import shutil  # noqa: PLC0415
    import uuid  # noqa: PLC0415

    sys.path.insert(0, str(kit))
    from hwtools.grade import blocks  # noqa: PLC0415
    from hwtools.grade.kits import write_submission  # noqa: PLC0415

    layout, name = blocks.load_layout(kit), f"hwgrade-bench-{uuid.uuid4().hex[:8]}"
    cpu, memory, used = Path("/sys/fs/cgroup/cpu") / name, Path("/sys/fs/cgroup/memory") / name, CPUACCT / name
    reference = private_reference(kit)
    for _ in range(count):
        with tempfile.TemporaryDirectory(prefix="bench-gradescope-") as folder:
            root = Path(folder) / "autograder"
            shutil.copytree(reference, root / "source")
            (root / "results").mkdir()
            fresh_submissions(write_submission, layout, folder, 1, "gs")[0].rename(root / "submission")
            for group in (cpu, memory, used):
                group.mkdir()
            try:
                (cpu / "cpu.cfs_period_us").write_text("100000")
                (cpu / "cpu.cfs_quota_us").write_text(str(int(GRADESCOPE_CPU * 100000)))
                (memory / "memory.limit_in_bytes").write_text(str(GRADESCOPE_MEMORY))
                join = 'echo $$ > "$1"; echo $$ > "$2"; echo $$ > "$3"; shift 3; exec "$@"'
                command = ["/bin/sh", "-c", join, "join", *(str(group / "cgroup.procs") for group in (cpu, memory, used)),
                           sys.executable, "-c", AUTOGRADE, str(root), isolation, python]
                started = time.perf_counter()
                run = subprocess.run(command, cwd=kit, env=dict(os.environ, PYTHONPATH=str(kit)), capture_output=True,
                                     text=True)
                seconds = time.perf_counter() - started
                peak = int((memory / "memory.max_usage_in_bytes").read_text()) / 2**20
                killed = (memory / "memory.failcnt").read_text().strip()
                seconds_cpu = int((used / "cpuacct.usage").read_text()) / 1e9
            finally:
                for group in (cpu, memory, used):
                    group.rmdir()
            data = json.loads((root / "results" / "results.json").read_text())
            assert run.returncode == 0 and data["score"] == AUTO_POINTS, (run.returncode, data.get("score"), run.stderr[-2000:])
            print(f"gradescope {data['extra_data']['sandbox']:<6} {GRADESCOPE_CPU:g} CPU, "
                  f"{GRADESCOPE_MEMORY // 2**20} MiB: {seconds:6.1f} s, peak {peak:5.0f} MiB (limit hit {killed} times); "
                  f"{seconds_cpu:.1f} CPU seconds, so {seconds_cpu / GRADESCOPE_CPU:.1f} s on a quiet half CPU", flush=True)
    shutil.rmtree(reference)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--submissions", type=int, default=5, help="timed submissions per setting (default 5)")
    parser.add_argument("--quick", action="store_true", help="one submission per setting")
    parser.add_argument("--baseline", metavar="REF", help="also measure the grader of this git revision, side by side")
    parser.add_argument("--isolation", nargs="+", default=["bwrap", "user", "none"], choices=["bwrap", "user", "none"])
    parser.add_argument("--jobs", nargs="+", type=int, default=[1], help="worker runs of one submission side by side")
    parser.add_argument("--bound", type=float, metavar="SECONDS", help="only: a submission of endless loops, this time limit")
    parser.add_argument("--gradescope", action="store_true", help="only: as Gradescope's default container (0.5 CPU, "
                                                                     "768 MiB), as root")
    parser.add_argument("--serve", nargs=4, metavar=("KIT", "ISOLATION", "JOBS", "PYTHON"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        serve(Path(args.serve[0]), args.serve[1], int(args.serve[2]), args.serve[3])
        return
    kit = Path(__file__).resolve().parents[1]
    count = 1 if args.quick else args.submissions
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPU(s), load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (a shared machine is noisy)")
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as folder:
        if args.gradescope:
            for isolation in args.isolation:
                gradescope(kit, count, isolation, user_python(folder) if isolation == "user" else "")
            return
        baseline = exported(args.baseline, kit, folder) if args.baseline else None
        if args.bound:
            for jobs in args.jobs:
                bound(kit, baseline, args.bound, jobs)
            return
        python = user_python(folder) if "user" in args.isolation else ""
        header = f"{'isolation':<10} {'jobs':>4}  {'first (+reference)':>18}  {'median':>16}  {'min':>6}  {'max':>6}"
        print(header + (f"  {'baseline ' + args.baseline:>24}  {'ratio':>6}" if baseline else ""))
        for jobs in args.jobs:
            for isolation in args.isolation:
                bench(kit, baseline, isolation, jobs, python if isolation == "user" else "", count)


def user_python(folder):
    """A Python the fallback's users can run, with this one's packages (the pool's users created)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from hwtools.grade.instructor import user_sandbox  # noqa: PLC0415

    user_sandbox.create_users()
    shared = Path(folder) / "user-python"
    shared.mkdir()
    for path in (shared, *shared.parents):  # the users must reach it
        if path == Path("/"):
            break
        path.chmod(path.stat().st_mode | 0o711)
    return user_sandbox.runnable_python(shared / "venv")


def bench(kit, baseline, isolation, jobs, python, count):
    """One line of the table: this kit (and the baseline) grading ``count`` fresh submissions in turns."""
    sides = [Side(kit, isolation, jobs, python)] + ([Side(baseline, isolation, jobs, python)] if baseline else [])
    times, cpus = [[] for _ in sides], [[] for _ in sides]
    for _ in range(count):
        for side, kept, used in zip(sides[::-1], times[::-1], cpus[::-1]):  # the baseline first, then this kit
            kept.append(side.grade())
            used.append(side.cpu)
    for side in sides:
        side.close()
    now = times[0]
    line = (f"{sides[0].ready['kind']:<10} {jobs:>4}  {sides[0].ready['setup']:>17.1f}s  "
            f"{statistics.median(now):>15.2f}s  {min(now):>5.2f}s  {max(now):>5.2f}s")
    if baseline:
        old = statistics.median(times[1])
        line += f"  {old:>16.2f}s ({sides[1].ready['kind']:<5})  {statistics.median(now) / old:>5.2f}x"
    if None not in cpus[0]:
        line += "  CPU " + " vs ".join(f"{statistics.median(used):.2f}s" for used in cpus)
    print(line, flush=True)


if __name__ == "__main__":
    main()
