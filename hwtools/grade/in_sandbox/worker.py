"""The entry point of every sandboxed grading process: ``python worker.py KIT_DIR [CPU_SECONDS MEMORY_BYTES OPEN_FILES]``.

It sets its own limits, keeps its standard input and output for the grader's messages (and
sends whatever the homework prints to the error stream instead), puts ``KIT_DIR`` first on its
path and hands over to the loop the grader copied into that kit (``KIT_DIR/_hwgrade/runtime.py``,
see ``runtime.py``): a process is the student's worker or the reference server according to
the first message it gets. This file must run on its own (the sandbox mounts it alone as
``/grader/worker.py``), so it imports nothing of ``hwtools``.
"""

from __future__ import annotations

import os
import sys


def _set_limits(cpu_seconds, memory_bytes, open_files):
    try:
        import resource  # noqa: PLC0415
    except ImportError:  # Windows: no such limits (the grader's wall clock still ends the run)
        return

    for limit, value in ((resource.RLIMIT_CPU, cpu_seconds), (resource.RLIMIT_AS, memory_bytes),
                         (resource.RLIMIT_NOFILE, open_files)):
        if value:
            soft, hard = resource.getrlimit(limit)
            value = value if hard == resource.RLIM_INFINITY else min(value, hard)
            resource.setrlimit(limit, (value, value))


def main(argv):
    kit_dir = os.path.realpath(argv[1])
    _set_limits(*(int(argv[index]) if len(argv) > index else 0 for index in (2, 3, 4)))
    requests, answers = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(2, 1)  # the homework's prints go to the error stream, never into the answers
    sys.stdout = sys.stderr
    script_dir = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [kit_dir] + [entry for entry in sys.path if entry and os.path.abspath(entry) != script_dir]
    sys.dont_write_bytecode = True
    import importlib  # noqa: PLC0415

    runtime = importlib.import_module("_hwgrade.runtime")
    if not os.path.realpath(runtime.__file__).startswith(kit_dir + os.sep):
        print("the grader's runtime was not found in the kit", file=sys.stderr)
        return 3
    return runtime.main(kit_dir, requests, answers)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
