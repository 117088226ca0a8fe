"""Load the user sandbox's seccomp filter, then run a program under it:

    /usr/bin/python3 -I confine.py -- PROGRAM [ARGS...]

Run by the system's Python (it has Debian's ``python3-seccomp``, the binding libseccomp itself
ships), already as the run's unprivileged user with ``no_new_privs`` (``setpriv``); the filter
stays on across ``exec`` and cannot be removed. It refuses, with EACCES/EPERM/ENOSYS:

* ``socket()`` of every family: no network, no Unix-socket daemons (``socketpair`` stays, it
  reaches nothing outside);
* ``io_uring_setup`` (it could open sockets around the filter);
* System V shared memory, semaphores and message queues (``shmget``, ``semget``, ``msgget``),
  POSIX message queues (``mq_open``) and kernel keyrings (``add_key``, ``request_key``,
  ``keyctl``): state outside any file that a later run could read;
* ``unshare``, ``setns``, and ``clone`` with namespace flags (``clone3``: ENOSYS, so that C
  libraries fall back to ``clone``, whose flags a filter can read).

System calls of a foreign architecture (32-bit ``int 0x80``) kill the process (libseccomp's
default). Standalone on purpose: standard library and ``seccomp`` only.
"""

import errno
import os
import sys

SHARED_STATE = ("shmget", "semget", "msgget", "mq_open", "add_key", "request_key", "keyctl")
# CLONE_NEWUSER, CLONE_NEWNET, CLONE_NEWPID, CLONE_NEWUTS, CLONE_NEWIPC, CLONE_NEWNS, CLONE_NEWCGROUP
NAMESPACE_FLAGS = (0x10000000, 0x40000000, 0x20000000, 0x04000000, 0x08000000, 0x00020000, 0x02000000)


def load_filter():
    import seccomp  # noqa: PLC0415 - the system's binding (python3-seccomp)

    rules = seccomp.SyscallFilter(defaction=seccomp.ALLOW)
    rules.add_rule(seccomp.ERRNO(errno.EACCES), "socket")
    for name in ("io_uring_setup", "unshare", "setns", *SHARED_STATE):
        rules.add_rule(seccomp.ERRNO(errno.EPERM), name)
    for flag in NAMESPACE_FLAGS:
        rules.add_rule(seccomp.ERRNO(errno.EPERM), "clone", seccomp.Arg(0, seccomp.MASKED_EQ, flag, flag))
    rules.add_rule(seccomp.ERRNO(errno.ENOSYS), "clone3")
    rules.load()


def main(argv):
    if os.getuid() == 0 or os.geteuid() == 0:
        sys.stderr.write("confine.py: refusing to run as root\n")
        return 126
    if "--" not in argv or argv.index("--") == len(argv) - 1:
        sys.stderr.write("usage: confine.py -- PROGRAM [ARGS...]\n")
        return 2
    program = argv[argv.index("--") + 1:]
    load_filter()
    os.execv(program[0], program)
    return 127


if __name__ == "__main__":
    sys.exit(main(sys.argv))
