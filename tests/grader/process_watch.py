"""Which processes of THIS test run are still alive: for the tests that prove a run leaves nothing behind.

Only this process's own descendants are looked at, so another grader or test run sharing the
machine is never counted. On import this process becomes a child subreaper
(``prctl(PR_SET_CHILD_SUBREAPER)``): a process that leaves its parent (a double fork, ``setsid``)
is then re-parented to this process instead of the machine's init, and stays in its tree, where
the scan finds it. Inside bubblewrap, orphans go to the sandbox's own init, a descendant too.
"""

import ctypes
import os
import time
from pathlib import Path

PR_SET_CHILD_SUBREAPER = 36


def become_subreaper():
    """Make this process the reaper of its orphaned descendants (Linux); True when it is."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


SUBREAPER = become_subreaper()


def _table():
    """{pid: (parent pid, state, command line)} of every process on the machine."""
    table = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        table[int(entry)] = (int(stat[1]), stat[0], cmdline)
    return table


def descendants(table, root):
    """The pids below ``root`` in ``table``."""
    children = {}
    for pid, (parent, _, _) in table.items():
        children.setdefault(parent, []).append(pid)
    found, pending = set(), [root]
    while pending:
        for child in children.get(pending.pop(), []):
            if child not in found:
                found.add(child)
                pending.append(child)
    return found


def live_processes(matches, settle=3.0, before=frozenset()):
    """The pids of this run's live descendants (zombies excluded) whose command line
    ``matches(cmdline bytes)``, but those in ``before`` (alive before what is judged began);
    processes that were just killed get up to ``settle`` seconds to go."""
    deadline = time.monotonic() + settle
    while True:
        reap_adopted_orphans()
        table = _table()
        found = {pid for pid in descendants(table, os.getpid()) - before
                 if table[pid][1] != "Z" and matches(table[pid][2])}
        if not found or time.monotonic() > deadline:
            return found
        time.sleep(0.1)


def real_uid(pid):
    """The real user id of process ``pid``, or None if it is gone."""
    try:
        with open(f"/proc/{pid}/status") as status:
            return int(next(line for line in status if line.startswith("Uid:")).split()[1])
    except (OSError, StopIteration, ValueError):
        return None


def adopted_zombies():
    """The zombies of other users among this process's children: orphans of the user fallback's
    runs (killed when their run ended) that this process adopted as a subreaper."""
    mine, me = os.getpid(), os.getuid()
    return [pid for pid, (parent, state, _) in _table().items()
            if parent == mine and state == "Z" and real_uid(pid) not in (None, me)]


def reap_adopted_orphans():
    """Reap ``adopted_zombies()``; returns how many. Until its parent reaps it, a zombie still
    counts against its user's process limit (``--nproc`` of the user fallback), so a later run of
    that pool user, in this test run or another one on the machine, could not fork. Children of
    this process's own user are left to their owners."""
    reaped = 0
    for pid in adopted_zombies():
        try:
            os.waitpid(pid, os.WNOHANG)
            reaped += 1
        except ChildProcessError:
            pass
    return reaped
