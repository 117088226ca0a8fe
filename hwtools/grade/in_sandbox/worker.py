"""The entry point of every sandboxed grading process: ``python worker.py KIT_DIR [CPU_SECONDS MEMORY_BYTES OPEN_FILES]``.

It sets its own limits, keeps its standard input and output for the grader's messages (and
sends whatever the homework prints to the error stream instead), puts ``KIT_DIR`` first on its
path and hands over to the loop the grader copied into that kit (``KIT_DIR/_hwgrade/runtime.py``,
see ``runtime.py``): a process is the student's worker or the reference server according to
the first message it gets. This file must run on its own (the sandbox mounts it alone as
``/grader/worker.py``), so it imports nothing of ``hwtools``.

Under bubblewrap a grading's runs are forked instead by its zygote (``instructor/zygote_init.py``),
which sets up each of them with ``_set_limits`` and ``_serve`` from here.
"""

from __future__ import annotations

import os
import sys


def set_limit(name, value, hard=True):
    """Put this process under the resource limit ``name`` (``"RLIMIT_AS"``, ``"RLIMIT_CPU"``, ...) of ``value``,
    never above the hard limit in force: soft and hard both (``hard``), else the soft limit alone, and only
    where it is higher. The one way the student's side sets a limit. Returns the soft limit then in force, or
    None where this system enforces no such limit: no ``resource`` module (Windows), no such limit, or the
    system refuses it (macOS refuses a finite RLIMIT_AS or RLIMIT_DATA: ``ValueError``, cpython#78783), said
    by no message: the grader's wall clock still ends a run."""
    try:
        import resource  # noqa: PLC0415
    except ImportError:
        return None
    which = getattr(resource, name, None)
    if which is None:
        return None
    try:
        soft, top = resource.getrlimit(which)
        value = value if top == resource.RLIM_INFINITY else min(value, top)
        if hard:
            resource.setrlimit(which, (value, value))
            return value
        if soft == resource.RLIM_INFINITY or soft > value:
            resource.setrlimit(which, (value, top))
            soft = value
        return soft
    except (ValueError, OSError):
        return None


def _set_limits(cpu_seconds, memory_bytes, open_files, file_bytes=0):
    for name, value in (("RLIMIT_CPU", cpu_seconds), ("RLIMIT_AS", memory_bytes), ("RLIMIT_NOFILE", open_files),
                        ("RLIMIT_FSIZE", file_bytes)):
        if value:
            set_limit(name, value)


def _serve(kit_dir):
    """Keep standard input and output for the grader's messages (the homework's prints go to the error
    stream, never into the answers), put ``kit_dir`` first on the path: (requests, answers)."""
    requests, answers = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    script_dir = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [kit_dir] + [entry for entry in sys.path if entry and os.path.abspath(entry) != script_dir]
    sys.dont_write_bytecode = True
    return requests, answers


def main(argv):
    kit_dir = os.path.realpath(argv[1])
    _set_limits(*(int(argv[index]) if len(argv) > index else 0 for index in (2, 3, 4)))
    requests, answers = _serve(kit_dir)
    import importlib  # noqa: PLC0415

    runtime = importlib.import_module("_hwgrade.runtime")
    if not os.path.realpath(runtime.__file__).startswith(kit_dir + os.sep):
        print("the grader's runtime was not found in the kit", file=sys.stderr)
        return 3
    return runtime.main(kit_dir, requests, answers)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
