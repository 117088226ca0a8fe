"""One control group per run of student code (Linux, the grader as root): the run as a whole, every
process it starts and every page of memory they use, files in a tmpfs (``/dev/shm``, ``/tmp``)
included, is bounded, whatever the number of processes it spreads over.

``RunGroup.make(memory)`` gives a group of at most MAX_PROCESSES processes (threads included) and
``memory`` bytes in all, or None where the machine does not let this process make one:

* cgroup v2 (``/sys/fs/cgroup`` unified) where the grader's own group is delegated to it, with the
  ``pids`` and ``memory`` controllers enabled for its children (``memory.max``, ``memory.swap.max``
  0, ``pids.max``);
* else cgroup v1, a group in each of the ``pids`` and ``memory`` hierarchies
  (``memory.limit_in_bytes``, ``pids.max``), made inside the grader's own groups.

A Docker container without privileges has ``/sys/fs/cgroup`` read-only: no group is made there, and
the per-process and per-user limits apply alone (docs/grading.md says which bound holds where).

The run's command is ``wrap``-ped: a shell, still root, writes its own pid into the group and
``exec``-s the command, so no code of the run executes outside it. ``close`` kills whatever is still
in the group (SIGKILL from root) and removes it.
"""

from __future__ import annotations

import os
import signal
import time
import uuid
from pathlib import Path

ROOT = Path("/sys/fs/cgroup")
MAX_PROCESSES = 64  # processes (threads included) of one run
KILL_SECONDS = 10.0  # the most ``close`` waits for the group's processes to go
JOIN = 'while [ "$1" != -- ]; do echo $$ > "$1" || exit 125; shift; done; shift; exec "$@"'


def _own_groups():
    """{controller or "" (v2): this process's group path} from /proc/self/cgroup."""
    groups = {}
    with open("/proc/self/cgroup", encoding="ascii") as table:
        for line in table:
            _, controllers, path = line.rstrip("\n").split(":", 2)
            for controller in controllers.split(",") if controllers else [""]:
                groups[controller] = path
    return groups


def _inside(mount, path):
    """The folder of group ``path`` under ``mount`` (the mount's root where the path is not visible)."""
    folder = mount / path.lstrip("/")
    return folder if folder.is_dir() else mount


def _write(path, text):
    with open(path, "w", encoding="ascii") as handle:
        handle.write(text)


class RunGroup:
    """The control group(s) of one run (``folders``), ``version`` 1 or 2."""

    def __init__(self, version, folders):
        self.version, self.folders = version, folders

    @classmethod
    def make(cls, memory, processes=MAX_PROCESSES):
        """A new group of at most ``processes`` processes and ``memory`` bytes, or None where this
        machine does not let this process make one."""
        if os.geteuid() != 0:
            return None
        name = f"hwgrade-run-{uuid.uuid4().hex[:12]}"
        try:
            groups = _own_groups()
        except (OSError, ValueError):
            return None
        if (ROOT / "cgroup.controllers").exists():
            return cls._make_v2(name, groups.get("", "/"), memory, processes)
        return cls._make_v1(name, groups, memory, processes)

    @classmethod
    def _make_v2(cls, name, own, memory, processes):
        parent = _inside(ROOT, own)
        try:
            enabled = (parent / "cgroup.subtree_control").read_text().split()
            if not {"pids", "memory"} <= set(enabled):
                _write(parent / "cgroup.subtree_control", "+pids +memory")
            folder = parent / name
            folder.mkdir()
        except OSError:
            return None
        group = cls(2, [folder])
        try:
            _write(folder / "pids.max", str(processes))
            _write(folder / "memory.max", str(memory))
            if (folder / "memory.swap.max").exists():
                _write(folder / "memory.swap.max", "0")
        except OSError:
            group.close()
            return None
        return group

    @classmethod
    def _make_v1(cls, name, groups, memory, processes):
        folders = []
        group = cls(1, folders)
        try:
            for controller, limits in (("pids", {"pids.max": processes}),
                                       ("memory", {"memory.limit_in_bytes": memory})):
                mount = ROOT / controller
                if controller not in groups or not (mount / "cgroup.procs").exists():
                    raise OSError(f"no cgroup v1 {controller} hierarchy")
                folder = _inside(mount, groups[controller]) / name
                folder.mkdir()
                folders.append(folder)
                for file, value in limits.items():
                    _write(folder / file, str(value))
        except OSError:
            group.close()
            return None
        return group

    def wrap(self, command):
        """``command`` started inside the group: a root shell joins it, then exec-s the command."""
        return ["/bin/sh", "-c", JOIN, "hwgrade-join", *[str(folder / "cgroup.procs") for folder in self.folders],
                "--", *command]

    def pids(self):
        """The processes in the group now."""
        found = set()
        for folder in self.folders:
            try:
                found |= {int(line) for line in (folder / "cgroup.procs").read_text().split()}
            except (OSError, ValueError):
                continue
        return found

    def _read(self, v1_file, v2_file, key=None):
        folder = self.folders[-1] if self.version == 1 and v1_file.startswith("memory") else self.folders[0]
        try:
            text = (folder / (v1_file if self.version == 1 else v2_file)).read_text()
        except (OSError, IndexError):
            return None
        if key is None:
            return int(text.split()[0]) if text.split() and text.split()[0].isdigit() else None
        fields = dict(line.split() for line in text.splitlines() if len(line.split()) == 2)
        return int(fields[key]) if fields.get(key, "").isdigit() else None

    def memory_peak(self):
        """The most bytes the run held at once (processes and tmpfs pages), where the kernel says."""
        return self._read("memory.max_usage_in_bytes", "memory.peak")

    def oom_kills(self):
        """How many of the run's processes the kernel killed for passing the memory bound."""
        return self._read("memory.oom_control", "memory.events", "oom_kill") or 0

    def close(self):
        """Kill every process still in the group (SIGKILL from root), wait for them KILL_SECONDS at
        most, remove the group; True when it is gone."""
        give_up = time.monotonic() + KILL_SECONDS
        if self.version == 2 and self.folders and (self.folders[0] / "cgroup.kill").exists():
            try:
                _write(self.folders[0] / "cgroup.kill", "1")
            except OSError:
                pass
        while True:
            left = self.pids()
            for pid in left:
                try:
                    os.kill(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            gone = True
            for folder in list(self.folders):
                try:
                    folder.rmdir()
                    self.folders.remove(folder)
                except FileNotFoundError:
                    self.folders.remove(folder)
                except OSError:
                    gone = False
            if gone or time.monotonic() > give_up:
                return gone
            time.sleep(0.02)


def describe(memory):
    """One line on how a run of ``memory`` bytes is bounded as a whole on this machine."""
    group = RunGroup.make(memory)
    if group is None:
        return ("no cgroup (not root, or /sys/fs/cgroup not writable): each process is bounded, the run as a whole "
                "is not (docs/grading.md)")
    group.close()
    return (f"each run in a cgroup v{group.version}: at most {MAX_PROCESSES} processes and "
            f"{memory // 2**20} MiB of memory in all, tmpfs files included")
