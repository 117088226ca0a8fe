"""Class grading benchmark: seconds per submission and for a class of 30, with 1 and 2 jobs, and an
estimate for a class of 300.

Run from the kit's root:  .venv/bin/python benchmarks/bench_classroom.py [--submissions 30] [--jobs 1 2]
                          [--isolation auto bwrap user none]

``--isolation`` compares the sandboxes side by side in one run: bubblewrap, the unprivileged-user
fallback of containers without namespaces (as root; its users are created, a Python they can run
is made from the system's with copies of the packages, as in the tests, and the reference is a
copy only root may read), and none.

Every submission is a zip (the kit one folder down, as a student zips their folder) whose blocks
hold the reference's code plus a comment of the submission's own, so that no TODO's kit matches
one the grader has run before: every TODO's sandboxed run happens, as in a real class where no
two students write the same code. Each setting starts from a new ``Grader`` and an empty saved
state. "first" is the first submission, which also computes the reference's answers (once per
class); the class's seconds come after it, graded by ``grade_class`` as the command line does.

The machine is shared while the kit is being built, so the numbers are noisy: the load average
is printed with them; benchmarks/RESULTS.md gives the ones measured, dated.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import zipfile
from pathlib import Path

from hwtools.grade import AUTO_POINTS, Grader, blocks, kits, submissions
from hwtools.grade.instructor import classroom, user_sandbox

KIT = Path(__file__).resolve().parents[1]


def make_class(layout, folder, count, tag):
    """``count`` zipped submissions, each with code of its own in every block."""
    reference = layout.reference_bodies()
    folder.mkdir(parents=True)
    for number in range(count):
        student = f"{tag}-{number:03d}"
        bodies = {todo: ["\n".join(body) + f"\n# {student}" for body in found] for todo, found in reference.items()}
        with tempfile.TemporaryDirectory() as scratch:
            kit = kits.write_submission(layout, Path(scratch) / "hw1", bodies)
            with zipfile.ZipFile(folder / f"{student}.zip", "w", compression=zipfile.ZIP_DEFLATED) as archive:
                for path in sorted(kit.rglob("*.py")):
                    archive.write(path, path.relative_to(kit.parent).as_posix())
    return folder


def own_cpu_group():
    """As root with cgroup v1: move this process (and so every process it starts) into a cpuacct group
    of its own; a function giving the CPU seconds that group has used, or None where there is none."""
    import atexit  # noqa: PLC0415
    import uuid  # noqa: PLC0415

    group = Path("/sys/fs/cgroup/cpuacct") / f"hwgrade-bench-{uuid.uuid4().hex[:8]}"
    try:
        group.mkdir()
        (group / "cgroup.procs").write_text(str(os.getpid()))
    except OSError:
        return None

    def leave():  # back to the group this process came from, and the group removed
        (group.parent / "cgroup.procs").write_text(str(os.getpid()))
        group.rmdir()

    atexit.register(leave)
    return lambda: int((group / "cpuacct.usage").read_text()) / 1e9


def bench(layout, workdir, count, jobs, isolation="auto", python=None, cpu=None):
    from bench_grading import private_reference  # noqa: PLC0415 - this folder is on the path when run as a script

    # under the user fallback the grader refuses a reference its users can read: a copy only root may enter
    reference = private_reference(KIT) if isolation == "user" else KIT
    grader = Grader(reference, jobs=1, isolation=isolation, python=python)
    jobs_tag = f"{jobs}-{isolation}"
    first = make_class(layout, workdir / f"first-{jobs_tag}", 1, f"first{jobs_tag}")
    started = time.perf_counter()
    report = classroom.grade_class(first, workdir / f"first-{jobs_tag}.csv", workdir / f"first-{jobs_tag}-feedback",
                                   grader=grader, jobs=1)
    first_seconds = time.perf_counter() - started
    assert report.students[0].auto_total == AUTO_POINTS, report.students[0].status
    folder = make_class(layout, workdir / f"class-{jobs_tag}", count, f"j{jobs_tag}")
    started, used = time.perf_counter(), cpu() if cpu else None
    report = classroom.grade_class(folder, workdir / f"class-{jobs_tag}.csv", workdir / f"class-{jobs_tag}-feedback",
                                   grader=grader, jobs=jobs)
    seconds, used = time.perf_counter() - started, cpu() - used if cpu else None
    assert report.graded_now == count and all(s.auto_total == AUTO_POINTS for s in report.students)
    grader.close()  # its reference servers and idle zygotes: none left in the CPU group at the end
    return grader.sandbox, first_seconds, seconds, used


def lying_zip_reading(workdir, entries=600_000):
    """(seconds, peak MiB) to reject a zip whose end record declares 1 entry while its central
    directory holds ``entries``: the reader's own count, and zipfile's parse (what the reader did
    before it counted the central directory itself)."""
    import struct  # noqa: PLC0415
    import tracemalloc  # noqa: PLC0415

    path = Path(workdir) / "lying.zip"
    records = [struct.pack("<4s6H3I5H2I", b"PK\x01\x02", 20, 20, 0, 0, 0, 0, 0, 0, 0, len(f"f{n}"), 0, 0, 0, 0, 0, 0)
               + f"f{n}".encode() for n in range(entries)]
    directory = b"".join(records)
    path.write_bytes(directory + struct.pack("<4s4H2IH", b"PK\x05\x06", 0, 0, 1, 1, len(directory), 0, 0))
    measured = {}
    for name, read in (("reader", lambda: submissions._zip_entry_count(path, submissions.MAX_ENTRIES)),
                       ("zipfile", lambda: len(zipfile.ZipFile(path).infolist()))):
        started = time.perf_counter()
        read()
        seconds = time.perf_counter() - started
        tracemalloc.start()  # the peak memory in a second pass (tracing slows the timing down)
        read()
        measured[name] = (seconds, tracemalloc.get_traced_memory()[1] / 2**20)
        tracemalloc.stop()
    return path.stat().st_size, measured


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--submissions", type=int, default=30, help="submissions in the class (default 30)")
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2], help="settings of --jobs (default: 1 2)")
    parser.add_argument("--zip-only", action="store_true", help="only the lying zip (600,000 entries declared as 1)")
    parser.add_argument("--isolation", nargs="+", default=["auto"], choices=["auto", "bwrap", "user", "none"],
                        help="sandboxes to compare (default: auto, the one the grader would pick)")
    args = parser.parse_args()
    if args.submissions < 1 or any(jobs < 1 for jobs in args.jobs):
        parser.error("--submissions and --jobs must be at least 1")
    layout = blocks.load_layout(KIT)
    with tempfile.TemporaryDirectory(prefix="bench-zip-") as workdir:
        size, measured = lying_zip_reading(workdir)
        print(f"a {size / 1e6:.0f} MB zip of 600,000 entries declared as 1: " + "; ".join(
            f"{name} {seconds:.2f} s, peak {peak:.0f} MiB" for name, (seconds, peak) in measured.items()))
    if args.zip_only:
        return
    load = os.getloadavg()
    print(f"{os.cpu_count()} CPU(s), load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
          "(a shared machine: the numbers are noisy)")
    print(f"{'sandbox':<8} {'jobs':>4}  {'first (+reference)':>18}  {f'class of {args.submissions}':>12}  "
          f"{'per submission':>14}  {'estimate for 300':>16}")
    cpu = own_cpu_group()  # the CPU every process of a class's grading used: what a quiet machine would take
    with tempfile.TemporaryDirectory(prefix="bench-classroom-") as workdir:
        python = None
        if "user" in args.isolation:  # a Python the fallback's users can run (this one may be under /root)
            user_sandbox.create_users()
            shared = Path(workdir) / "user-python"
            shared.mkdir()
            os.chmod(workdir, 0o755)
            python = user_sandbox.runnable_python(shared / "venv")
        for isolation in args.isolation:
            for jobs in args.jobs:
                box, first, seconds, used = bench(layout, Path(workdir), args.submissions, jobs, isolation,
                                                  python if isolation == "user" else None, cpu)
                per = seconds / args.submissions
                estimate = first + 300 * per
                line = (f"{box.kind:<8} {jobs:>4}  {first:>17.1f}s  {seconds:>11.1f}s  "
                        f"{per:>13.2f}s  {estimate / 60:>13.1f} min")
                if used is not None:  # a quiet machine: the class's CPU spread over min(jobs, cores) cores
                    per_cpu = used / args.submissions
                    line += (f"; CPU {per_cpu:.2f} s a submission, 300 on {min(jobs, os.cpu_count())} core(s) "
                             f"≈ {300 * per_cpu / min(jobs, os.cpu_count()) / 60:.1f} min")
                print(line, flush=True)
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
