"""The sandbox where bubblewrap cannot create namespaces (Docker's default seccomp profile refuses
them, as on Gradescope): each run as an unprivileged user of its own, without network sockets, on a
kit folder only that run can read.

    python -m hwtools.grade.instructor.user_sandbox create [--count 8]    # once, as root (setup.sh does it)
    python -m hwtools.grade.instructor.user_sandbox python FOLDER          # a Python those users can run (rm -r it after)

What a run gets (the grader must run as root to start it):

* a user of the pool ``hwgrade1`` ... ``hwgradeN`` (``create``) that no other run holds at the same
  time (a lock per user, across processes), switched to with ``setpriv``: its own uid and group, no
  supplementary groups, no capabilities, ``no_new_privs``;
* the seccomp filter of every run (``confine.py``, with Debian's ``python3-seccomp``: libseccomp's
  own binding), which refuses every new file, folder, link or other entry on any disk (and every
  removal or renaming of one), every socket, io_uring, new namespaces, System V IPC, POSIX message
  queues, keyrings and memory files: where it may write (``/tmp``, its home on the host's disk) no
  file system of the run's own can be mounted (Docker without privileges) and no quota is set, so
  the kernel refuses its files outright, and nothing it could leave outlives it;
* the kit, the worker and a home folder in a private folder (``root:<the run's group>``, 0750), deleted
  after the run;
* the same CPU, memory, file-size and open-file limits as in bubblewrap and a cap on its processes.

When the run ends every process of its user is killed, found by uid (``kill(-1)`` as that user,
then SIGKILL from root to each one a ``/proc`` scan finds, until none is left), so a child that left
the process group, cleared its environment or called ``setsid`` dies too. The grader never forks
to become a pool user: it starts ``setpriv`` with ``close_fds`` (``as_user``: no lock of the grader
reaches a process a student's code can stop) and waits for it KILL_SECONDS at most, then root
kills it with SIGKILL, which ends a stopped process too.
Not hidden (no namespaces): the host's process list and
command lines, and every file that any user may read. So the reference kit must not be readable
by other users: the grader checks it as each pool user (``readable_by_pool``) and refuses to
grade while one can (the Gradescope autograder makes its ``source/`` root-only and deletes the
reference once loaded).

The Python that runs the worker must be one the pool's users can run whatever the permissions of
the folder the kit was cloned into: ``runnable_python`` makes a virtual environment of the
system's Python in a folder of its own, with real copies of the installed packages the graded
code imports (``GRADED_PACKAGES`` and what they require), never a path into someone's private
folder (``setup.sh`` does the same with pip on Gradescope).
"""

from __future__ import annotations

import argparse
import fcntl
import functools
import json
import os
import pwd
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from hwtools.grade.instructor.cgroups import MAX_PROCESSES  # processes (threads included) of one run (its user's limit too)

CONFINE = Path(__file__).resolve().with_name("confine.py")
SYSTEM_PYTHON = "/usr/bin/python3"  # the system's Python, which has Debian's python3-seccomp
USER_NAME = re.compile(r"^hwgrade(\d+)$")
DEFAULT_USERS = 8
KILL_SECONDS = 10.0  # the most the grader waits for a process it started as a pool user before root kills it
KILL = ("/bin/kill", "-s", "KILL", "--", "-1")  # kill(1) (procps or util-linux): every process of its user
LOCK_DIR = Path("/run/hwgrade-sandbox")
GRADED_PACKAGES = ("numpy", "gymnasium")  # what hwlib imports when the worker loads it (with their requirements)
_THREAD_LOCK = threading.Lock()
_HELD = set()  # users held by runs of this process


def users():
    """The pool's accounts (pwd entries ``hwgrade<N>``, never uid 0), by number."""
    found = []
    for entry in pwd.getpwall():
        match = USER_NAME.match(entry.pw_name)
        if match and entry.pw_uid != 0 and entry.pw_gid != 0:
            found.append((int(match[1]), entry))
    return [entry for _, entry in sorted(found)]


def create_users(count=DEFAULT_USERS):
    """Create the pool's missing accounts (system users, own group, no home, no login shell); their names."""
    if os.geteuid() != 0:
        raise PermissionError("only root can create the sandbox's users")
    shell = "/usr/sbin/nologin" if os.path.exists("/usr/sbin/nologin") else "/bin/false"
    names = []
    for number in range(1, count + 1):
        name = f"hwgrade{number}"
        try:
            pwd.getpwnam(name)
        except KeyError:
            subprocess.run(["useradd", "--system", "--user-group", "--no-create-home", "--home-dir", "/nonexistent",
                            "--shell", shell, "--comment", "sandbox of the HW1 grader", name], check=True)
        names.append(name)
    return names


def _lock_dir():
    LOCK_DIR.mkdir(mode=0o700, exist_ok=True)
    info = LOCK_DIR.stat()
    if info.st_uid != 0 or info.st_mode & 0o077:
        raise PermissionError(f"{LOCK_DIR} must be root's alone")
    return LOCK_DIR


def _take(entry):
    """The lock file of pool user ``entry``, locked for this caller, or None if a run holds it."""
    with _THREAD_LOCK:
        if entry.pw_name in _HELD:
            return None
        handle = open(_lock_dir() / f"{entry.pw_name}.lock", "w")  # noqa: SIM115 - held until released
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            return None
        _HELD.add(entry.pw_name)
        return handle


class _Slot:
    """One pool user held by one run: a thread lock in this process and a file lock across processes."""

    def __init__(self, wait=600.0, user=None):
        pool = [user] if user is not None else users()
        if not pool:
            raise RuntimeError("no sandbox users: create them as root with python -m hwtools.grade.instructor.user_sandbox create")
        give_up = time.monotonic() + wait
        while True:
            for entry in pool:
                handle = _take(entry)
                if handle is not None:
                    self.user, self._handle = entry, handle
                    return
            if time.monotonic() > give_up:
                raise TimeoutError("every sandbox user stayed busy")
            time.sleep(0.05)

    def release(self):
        with _THREAD_LOCK:
            _HELD.discard(self.user.pw_name)
            self._handle.close()


def processes_of(uid):
    """Live (not zombie) processes any of whose user ids is ``uid``."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/status", encoding="ascii", errors="replace") as status:
                fields = dict(line.split(":", 1) for line in status if ":" in line)
        except OSError:
            continue
        if fields.get("State", "").strip().startswith("Z"):
            continue
        if str(uid) in fields.get("Uid", "").split():
            found.append(int(entry))
    return found


def as_user(uid, gid, argv, timeout=None):
    """Run ``argv`` as user ``uid`` of group ``gid`` (``setpriv``, no supplementary groups) in a
    process of its own: no descriptor of the grader (``close_fds``: it holds no lock a student's
    process could keep held), its own session, an empty environment. (exit code, standard output);
    at ``timeout`` (default KILL_SECONDS) root kills it with SIGKILL, which ends a stopped process
    too: then (None, b"")."""
    process = subprocess.Popen([_setpriv(), f"--reuid={uid}", f"--regid={gid}", "--clear-groups", "--", *argv],
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               close_fds=True, start_new_session=True, env={"PATH": "/usr/bin:/bin"}, cwd="/")
    try:
        output, _ = process.communicate(timeout=KILL_SECONDS if timeout is None else timeout)
        return process.returncode, output
    except subprocess.TimeoutExpired:
        process.kill()
        try:  # its output pipe may be held by a process it started: that is no reason to wait longer
            process.communicate(timeout=KILL_SECONDS)
        except subprocess.TimeoutExpired:
            process.stdout.close()
            process.wait(timeout=KILL_SECONDS)
        return None, b""


def _setpriv():
    return shutil.which("setpriv", path="/usr/bin:/bin") or "setpriv"


def kill_user(uid, gid, rounds=50):
    """Kill every process of ``uid``: ``kill(-1, SIGKILL)`` as that user (one system call reaches all
    of them, forks included; a ``setpriv`` process, never a fork of the grader, killed by root if it
    is not done in KILL_SECONDS: a process of the user may stop it), then SIGKILL from root to each
    one a ``/proc`` scan finds, until a scan finds none. True when none is left."""
    as_the_user = True
    for _ in range(rounds):
        if as_the_user:
            code, _ = as_user(uid, gid, list(KILL))
            as_the_user = code is not None  # stopped or held: root's scan alone from now on
        left = processes_of(uid)
        if not left:
            return True
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.02)
    return not processes_of(uid)


def kill_all_users():
    """Kill every process of every pool user that no run holds (before results are written); True
    when none is left. Each user is taken first, as a run takes it: one that another grader on the
    same machine holds is that grader's to clean up (its run kills them when it ends), never killed
    in its middle. (On Gradescope one grader has the container: every user is free by then.)"""
    done = True
    for entry in users():
        handle = _take(entry)
        if handle is None:
            continue
        try:
            done = kill_user(entry.pw_uid, entry.pw_gid) and done
        finally:
            with _THREAD_LOCK:
                _HELD.discard(entry.pw_name)
                handle.close()
    return done


def _own(path, uid, gid, mode):
    os.chown(path, uid, gid, follow_symlinks=False)
    os.chmod(path, mode)


class RunFolder:
    """The private folder of one run, holding a pool user until ``end``: ``kit``, ``worker``,
    ``confine`` (read-only for the run), ``home`` (its own)."""

    def __init__(self, kit_dir, worker):
        self._slot = _Slot()
        self.uid, self.gid = self._slot.user.pw_uid, self._slot.user.pw_gid
        self._ended, self._gone = False, True
        try:
            if not kill_user(self.uid, self.gid):  # what a crashed grader's run may have left running
                raise RuntimeError(f"a process of {self._slot.user.pw_name} could not be killed")
            self.base = Path(tempfile.mkdtemp(prefix="hwgrade-user-"))
            _own(self.base, 0, self.gid, 0o750)
            self.kit = self.base / "kit"
            shutil.copytree(kit_dir, self.kit, symlinks=False)
            for folder, names, files in os.walk(self.kit):
                _own(folder, 0, self.gid, 0o750)
                for name in files:
                    _own(os.path.join(folder, name), 0, self.gid, 0o640)
            grader = self.base / "grader"
            grader.mkdir()
            _own(grader, 0, self.gid, 0o750)
            self.worker, self.confine = grader / "worker.py", grader / "confine.py"
            for source, target in ((worker, self.worker), (CONFINE, self.confine)):
                shutil.copyfile(source, target)
                _own(target, 0, self.gid, 0o640)
            self.home = self.base / "home"
            self.home.mkdir()
            _own(self.home, self.uid, self.gid, 0o700)
        except BaseException:
            self.end()
            raise

    def command(self, python):
        """The command line that runs ``python`` on the worker as this run's user, confined."""
        return [shutil.which("setpriv") or "setpriv", f"--reuid={self.uid}", f"--regid={self.gid}", "--clear-groups",
                "--no-new-privs", "--inh-caps=-all", "--bounding-set=-all", "--",
                SYSTEM_PYTHON, "-I", str(self.confine), "--", os.path.abspath(python), "-B", "-s", str(self.worker),
                str(self.kit)]

    def end(self):
        """Kill every process of the run's user, delete the folder, free the user (once). True when
        no process of the user is left (else no run may begin after it). The user made no file
        anywhere (``confine.py``): there is nothing else of it to look for."""
        if self._ended:
            return self._gone
        self._ended, self._gone = True, False
        try:
            self._gone = kill_user(self.uid, self.gid)
            if getattr(self, "base", None) is not None:
                shutil.rmtree(self.base, ignore_errors=True)
        finally:
            self._slot.release()
        return self._gone


PROBE_CODE = ("import os, socket, numpy\n"
              "try:\n    socket.socket(socket.AF_INET, socket.SOCK_STREAM)\n    print('network')\n"
              "except OSError:\n    print('confined', os.getuid())\n")


@functools.lru_cache(maxsize=None)
def probe(python):
    """(True, how) if runs as a pool user work here for ``python``, else (False, why not)."""
    if os.geteuid() != 0:
        return False, "the grader is not root, so it cannot run code as another user"
    pool = users()
    if not pool:
        return False, "no sandbox users (as root: python -m hwtools.grade.instructor.user_sandbox create; setup.sh does it)"
    for tool in ("setpriv", "prlimit"):  # prlimit: a run's limits (its processes, file size, open files...)
        if not shutil.which(tool):
            return False, f"{tool} (util-linux) is missing"
    try:
        check = subprocess.run([SYSTEM_PYTHON, "-I", "-c", "import seccomp; print(seccomp.get_api())"],
                               capture_output=True, text=True, timeout=60, env={})
    except (OSError, subprocess.TimeoutExpired) as error:
        return False, f"{SYSTEM_PYTHON} cannot run: {error}"
    if check.returncode != 0:
        return False, (f"{SYSTEM_PYTHON} has no seccomp module (Debian/Ubuntu: apt-get install python3-seccomp)")
    with tempfile.TemporaryDirectory(prefix="hwgrade-probe-") as kit:
        try:
            folder = RunFolder(kit, CONFINE)
        except (RuntimeError, TimeoutError, OSError) as error:
            return False, f"no run folder: {error}"
        try:
            command = folder.command(python)
            command[command.index(str(folder.worker)):] = ["-c", PROBE_CODE]
            result = subprocess.run(command, capture_output=True, text=True, timeout=60, env={"PATH": "/usr/bin:/bin"},
                                    cwd=folder.home, stdin=subprocess.DEVNULL)
        except (OSError, subprocess.TimeoutExpired) as error:
            return False, f"a run as {folder._slot.user.pw_name} could not start: {error}"
        finally:
            folder.end()
    if result.stdout.split() != ["confined", str(folder.uid)]:
        reason = " ".join((result.stderr or result.stdout).split())[-300:]
        return False, f"{python} does not run confined as {pool[0].pw_name} ({reason or result.returncode})"
    return True, (f"unprivileged user per run ({len(pool)} users {pool[0].pw_name}..{pool[-1].pw_name}), "
                  f"network sockets refused by seccomp, a private kit folder, every process of the user killed "
                  f"at the end; no namespaces: the host's processes and world-readable files are visible")


_OPENABLE = ("import os, sys\n"
             "for number, path in enumerate(sys.argv[1:]):\n"
             "    try:\n        os.close(os.open(path, os.O_RDONLY))\n        print(number)\n"
             "    except OSError:\n        pass\n")


def readable_by_pool(paths, timeout=60.0):
    """The ``paths`` that a user of the pool can open for reading, tried as each of them (``as_user``),
    each while holding that user (``_Slot``): no run of the user, in this grading process or another,
    can stop, kill or answer for the try. A try that fails or does not finish in ``timeout`` seconds
    counts every path as readable (fail closed)."""
    paths, found = [str(path) for path in paths], set()
    for entry in users():
        slot = _Slot(user=entry)
        try:
            code, output = as_user(entry.pw_uid, entry.pw_gid, [SYSTEM_PYTHON, "-I", "-c", _OPENABLE, *paths], timeout)
        finally:
            slot.release()
        if code != 0:
            return sorted(paths)
        found |= {paths[int(number)] for number in output.split() if number.isdigit() and int(number) < len(paths)}
    return sorted(found)


_DISTRIBUTION_FILES = r"""
import importlib.metadata as metadata, json, os, re, sys, sysconfig
site = os.path.realpath(sysconfig.get_paths()["purelib"])
pending, seen, files = list(sys.argv[1:]), set(), []
while pending:
    name = pending.pop()
    key = re.sub(r"[-_.]+", "-", name).lower()
    if key in seen:
        continue
    seen.add(key)
    try:
        dist = metadata.distribution(name)
    except metadata.PackageNotFoundError:
        continue  # a requirement of another Python version or platform
    pending += [re.match(r"[A-Za-z0-9_.-]+", line)[0] for line in dist.requires or [] if "extra ==" not in line]
    for item in dist.files or []:
        path = os.path.realpath(dist.locate_file(item))
        if path.startswith(site + os.sep) and os.path.isfile(path):
            files.append(os.path.relpath(path, site))
print(json.dumps({"site": site, "files": sorted(set(files))}))
"""


def runnable_python(folder, python=sys.executable, packages=GRADED_PACKAGES):
    """A virtual environment in ``folder`` made from the system's Python that the pool's users can
    run, with real copies of ``python``'s installed ``packages`` and every distribution they
    require (``python`` may live where those users cannot reach, as under /root or in a clone inside
    a private folder). Both must be the same Python version. The folder is root's to write and
    everyone's to read; delete it when done. Returns the new Python's path."""
    folder = Path(folder)
    subprocess.run([SYSTEM_PYTHON, "-m", "venv", "--without-pip", str(folder)], check=True, capture_output=True)
    new = folder / "bin" / "python"
    versions = [subprocess.run([str(candidate), "-c", "import sys; print(sys.version_info[:2])"], capture_output=True,
                               text=True, check=True).stdout for candidate in (new, python)]
    if versions[0] != versions[1]:
        raise RuntimeError(f"{SYSTEM_PYTHON} is Python {versions[0].strip()}, {python} is {versions[1].strip()}")
    found = json.loads(subprocess.run([python, "-I", "-c", _DISTRIBUTION_FILES, *packages], capture_output=True,
                                      text=True, check=True).stdout)
    site = Path(subprocess.run([str(new), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    for relative in found["files"]:
        target = site / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(found["site"]) / relative, target)
    for path in [folder, *folder.rglob("*")]:
        if not path.is_symlink():
            path.chmod(0o755 if path.is_dir() or os.access(path, os.X_OK) else 0o644)
    return str(new)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m hwtools.grade.instructor.user_sandbox", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    create = commands.add_parser("create", help="create the pool's users (as root)")
    create.add_argument("--count", type=int, default=DEFAULT_USERS)
    python = commands.add_parser("python", help="make a Python the pool's users can run (a venv in FOLDER, with "
                                                "real copies of this Python's packages that graded code imports; "
                                                "rm -r FOLDER after)")
    python.add_argument("folder", help="a new folder, in a place the pool's users can reach (not under /root)")
    commands.add_parser("probe", help="say whether runs as a pool user work here")
    args = parser.parse_args(argv)
    if args.command == "create":
        print("sandbox users:", " ".join(create_users(args.count)))
    elif args.command == "python":
        python = runnable_python(args.folder)
        print(python)
        works, how = probe(python) if os.geteuid() == 0 and users() else (False, "not checked (not root, or no users)")
        if not works:
            print(f"warning: the pool's users cannot run it ({how}): the folders above it must let them in",
                  file=sys.stderr)
    else:
        works, how = probe(sys.executable)
        print(("user sandbox: " if works else "no user sandbox: ") + how)
        return 0 if works else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
