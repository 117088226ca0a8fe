"""The seccomp filter of every run of student code, both launchers':

    /usr/bin/python3 -I confine.py -- PROGRAM [ARGS...]   # the user fallback: load it, then run PROGRAM under it
    /usr/bin/python3 -I confine.py --bpf                  # bubblewrap: write it, compiled, to standard output

Run by the system's Python (it has Debian's ``python3-seccomp``, the binding libseccomp itself
ships). The user fallback runs it already as the run's unprivileged user with ``no_new_privs``
(``setpriv``); bubblewrap loads the compiled program (``bwrap --seccomp FD``) just before it starts
the worker. A filter stays on across ``exec`` and ``fork`` and cannot be removed. It refuses:

* **every new file, of every kind** (EROFS, as a read-only disk would): ``open``/``openat`` with
  ``O_CREAT`` or ``O_TMPFILE`` (flags the filter reads in the call's registers; ``openat2``, whose
  flags it cannot read, ENOSYS, so that a C library falls back to ``openat``), ``creat``,
  ``mkdir*``, ``mknod*`` (fifos, sockets), ``symlink*``, ``link*``, ``rename*``, and the removal of
  any name (``unlink*``, ``rmdir``: the run has none of its own, and another user's may sit in a
  folder every user may write without the sticky bit); preallocated space (``fallocate``:
  EOPNOTSUPP, so that ``posix_fallocate`` writes instead, under the file-size limit). Why refused
  calls: the user fallback's runs write where every user may (``/tmp``, a home on the host's
  disk), where no size-limited file system of the run's own can be mounted (Docker without
  privileges, Gradescope) and no quota is set; bubblewrap's tmpfs mounts bound bytes but not their
  number of files (each one, an empty file or a symlink, holds kernel memory). The worker writes
  nothing (its answers go to standard output, its prints to the error stream the grader opened),
  nor do Python (``-B``), numpy or gymnasium at import. So a run holds no disk at any moment, on
  every launcher, with no polling, but what it writes into files that exist already and it may
  write (its error stream; under the user fallback a world-writable file of the host), each under
  the file-size limit; and nothing it could leave outlives it;
* **every socket** (EACCES): ``socket()`` of every family (no network, no Unix-socket daemons) and
  ``socketpair``, so no descriptor is ever in flight (SCM_RIGHTS) and no socket buffer holds memory;
* memory that a run holds outside its address-space limit where no cgroup counts it:
  ``memfd_create`` and ``memfd_secret`` (files of no file system), System V shared memory,
  semaphores and message queues (``shmget``, ``semget``, ``msgget``), POSIX message queues
  (``mq_open``), kernel keyrings (``add_key``, ``request_key``, ``keyctl``), BPF maps (``bpf``),
  byte-range locks (``fcntl``'s F_SETLK, F_SETLKW and their OFD twins: ENOLCK; each lock is kernel
  memory, and a file may hold any number), watches that pin files (``inotify_init*``,
  ``fanotify_init``), pipes made bigger than their default 16 pages (``fcntl(F_SETPIPE_SZ)``), and
  pages moved into pipes by reference (``splice``, ``vmsplice``, ``tee``): what is left is each
  pipe's 16 pages, bounded by the open-file and process limits (docs/grading.md);
* ``io_uring_setup`` (its requests bypass this filter);
* ``setsid``: every process of a run stays in the session the run starts in (bubblewrap's
  ``--new-session``, the user fallback's ``setpriv`` in a session of its own), so the scheduler's
  autogroup gives the run as a whole one share of the CPU, however many processes it forks;
* ``unshare``, ``setns``, and ``clone`` with namespace flags (``clone3``: ENOSYS, so that C
  libraries fall back to ``clone``, whose flags a filter can read): no namespace of the run's own,
  where it could mount a file system or become root.

System calls of a foreign architecture (32-bit ``int 0x80``) kill the process (libseccomp's
default). Standalone on purpose: standard library and ``seccomp`` only.
"""

import errno
import os
import sys

SHARED_STATE = ("shmget", "semget", "msgget", "mq_open", "add_key", "request_key", "keyctl", "memfd_create",
                "memfd_secret", "splice", "vmsplice", "tee", "bpf", "inotify_init", "inotify_init1", "fanotify_init",
                "io_uring_setup", "unshare", "setns", "setsid")
NAMES = ("creat", "mkdir", "mkdirat", "mknod", "mknodat", "symlink", "symlinkat", "link", "linkat", "rename",
         "renameat", "renameat2", "unlink", "unlinkat", "rmdir")  # every call that adds, removes or renames a name
O_CREAT, O_TMPFILE = 0o100, 0o20000000  # (O_TMPFILE's own bit; glibc's O_TMPFILE adds O_DIRECTORY)
F_SETPIPE_SZ = 1031
LOCKS = (6, 7, 37, 38)  # fcntl's F_SETLK, F_SETLKW, F_OFD_SETLK, F_OFD_SETLKW
# CLONE_NEWUSER, CLONE_NEWNET, CLONE_NEWPID, CLONE_NEWUTS, CLONE_NEWIPC, CLONE_NEWNS, CLONE_NEWCGROUP
NAMESPACE_FLAGS = (0x10000000, 0x40000000, 0x20000000, 0x04000000, 0x08000000, 0x00020000, 0x02000000)


def rules():
    import seccomp  # noqa: PLC0415 - the system's binding (python3-seccomp)

    found = seccomp.SyscallFilter(defaction=seccomp.ALLOW)

    def refuse(error, name, *args):
        found.add_rule(seccomp.ERRNO(error), name, *args)

    for name in ("socket", "socketpair"):
        refuse(errno.EACCES, name)
    for name in SHARED_STATE:
        refuse(errno.EPERM, name)
    for name in NAMES:
        refuse(errno.EROFS, name)
    for flag in (O_CREAT, O_TMPFILE):
        refuse(errno.EROFS, "open", seccomp.Arg(1, seccomp.MASKED_EQ, flag, flag))
        refuse(errno.EROFS, "openat", seccomp.Arg(2, seccomp.MASKED_EQ, flag, flag))
    refuse(errno.ENOSYS, "openat2")
    refuse(errno.EOPNOTSUPP, "fallocate")
    refuse(errno.EPERM, "fcntl", seccomp.Arg(1, seccomp.MASKED_EQ, 0xFFFFFFFF, F_SETPIPE_SZ))  # cmd: an int
    for command in LOCKS:
        refuse(errno.ENOLCK, "fcntl", seccomp.Arg(1, seccomp.MASKED_EQ, 0xFFFFFFFF, command))
    for flag in NAMESPACE_FLAGS:
        refuse(errno.EPERM, "clone", seccomp.Arg(0, seccomp.MASKED_EQ, flag, flag))
    refuse(errno.ENOSYS, "clone3")
    return found


def main(argv):
    if argv[1:] == ["--bpf"]:
        rules().export_bpf(sys.stdout)
        return 0
    if os.getuid() == 0 or os.geteuid() == 0:
        sys.stderr.write("confine.py: refusing to run as root\n")
        return 126
    if "--" not in argv or argv.index("--") == len(argv) - 1:
        sys.stderr.write("usage: confine.py -- PROGRAM [ARGS...] | confine.py --bpf\n")
        return 2
    program = argv[argv.index("--") + 1:]
    rules().load()
    os.execv(program[0], program)
    return 127


if __name__ == "__main__":
    sys.exit(main(sys.argv))
