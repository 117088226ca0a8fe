"""The sandbox the grader runs students' code in: what the code can see and do, and the limits.

Each test runs the worker on a tiny kit whose ``sigmoid`` does what the test needs (try the
network, look for the instructor's files, allocate memory...) and returns numbers saying what
happened. Three sandboxes: ``isolated`` (bubblewrap), ``user`` (the fallback without namespaces:
an unprivileged user per run; the pool's users are created here as ``setup.sh`` creates them,
and a Python those users can run is made from the system's), and ``plain`` (none). Tests of an
isolation skip where it cannot run (the grader then says NOT ISOLATED); the limits hold in all.
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hwtools.grade import broker, kits, sandbox
from hwtools.grade.instructor import bwrap_sandbox, cgroups, user_sandbox
from hwtools.grade.instructor.zygote import Zygotes
from hwtools.grade.in_sandbox import channel
from hwtools.grade.sandbox import Sandbox
import containers
from process_watch import SUBREAPER, adopted_zombies, live_processes, real_uid, reap_adopted_orphans

KIT = Path(__file__).resolve().parents[2]
CANARY = "HWGRADE_CANARY"

pytestmark = pytest.mark.timeout(300)


LEAVE_SESSION = textwrap.dedent("""
    def leave_session():  # a child's escape from the run's session, where it may (the sandboxes' filter refuses it)
        try:
            os.setsid()
        except OSError:
            pass
""")


def make_kit(folder, body):
    """A kit whose hwlib.logreg.sigmoid(z) runs ``body`` (which sets ``values`` and may call
    ``leave_session()``), with the grader's process side (``_hwgrade/``) that every kit the grader
    runs holds."""
    package = folder / "kit" / "hwlib"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    code = "import os, sys, time\nimport numpy as np\n\n\n" + LEAVE_SESSION + "\n\ndef sigmoid(z):\n" + \
        textwrap.indent(body, "    ") + "\n    return values\n"
    (package / "logreg.py").write_text(code)
    for relative, text in kits.sandboxed_files().items():
        (folder / "kit" / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / "kit" / relative).write_text(text)
    return folder / "kit"


def run(kit, box, cases=1, time_limit=None):
    """A worker on ``kit`` run through cases c0, c1, ... of the sigmoid probe (z = [i]) as the grader
    drives it, nothing served: (how the run ended, {case id: result} of the answered cases)."""
    cases = [(f"c{i}", "sigmoid", {"z": np.array([float(i)])}) for i in range(cases)]
    return broker.run_cases(box.start(kit, time_limit), None, cases, [], None)


def values(ran):
    outcome, results = ran
    assert outcome.status == "ok", (outcome.status, outcome.detail, outcome.stderr_tail)
    result = results["c0"]
    assert result["status"] == "ok", result["error"]
    return result["values"]["values"]


@pytest.fixture(scope="module")
def isolated():
    box = Sandbox(python=sandbox.sys.executable, isolation="auto", time_limit=30)
    if not box.isolated:
        pytest.skip(f"no sandbox here: {box.how}")
    return box


@pytest.fixture(scope="module")
def plain():
    return Sandbox(python=sandbox.sys.executable, isolation="none", time_limit=30)


@pytest.fixture(scope="module")
def user_python():
    """A Python the pool's users can run (this one may live under /root), with this one's packages."""
    folder, python = containers.user_sandbox_python()
    yield python
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture()
def fake_bwrap(tmp_path):
    return containers.fake_bwrap_folder(tmp_path / "docker-bin")


@pytest.fixture(scope="module")
def user(user_python):
    return Sandbox(python=user_python, isolation="user", time_limit=30)


# the kit a zygote compiles when it starts: a sigmoid that answers -1, which no test's kit does
TEMPLATE = {"hwlib/__init__.py": "", "hwlib/logreg.py": "import numpy as np\n\n\ndef sigmoid(z):\n    return "
            "np.array([-1.0])\n"}


class Forked:
    """``isolated`` with every run forked by the zygote of one grading (``Budget.zygote``), as a
    grader's runs of student code are under bubblewrap, the zygote's template ``TEMPLATE``."""

    def __init__(self, box):
        self.box, self.zygotes = box, Zygotes(box)
        self.grading = sandbox.Budget(3600, self.zygotes.take(TEMPLATE))

    def start(self, kit, time_limit=None, trusted=False, budget=None):
        return self.box.start(kit, time_limit, trusted, self.grading)

    def __getattr__(self, name):
        return getattr(self.box, name)


@pytest.fixture()
def zygote(isolated):
    if isolated.kind != "bwrap":
        pytest.skip("bubblewrap does not work here")
    forked = Forked(isolated)
    yield forked
    forked.grading.close()
    forked.zygotes.close()


@pytest.mark.parametrize("mode", ["isolated", "user"])
def test_no_network(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        import socket
        try:
            socket.create_connection(("1.1.1.1", 53), timeout=3).close()
            values = np.array([1.0])
        except OSError:
            values = np.array([0.0])
    """))
    assert values(run(kit, box)).tolist() == [0.0]


def test_sees_only_its_kit_python_and_a_fresh_tmp(isolated, tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("the reference")
    # The sandbox's /tmp is fresh: it holds its home and, where the kit or its Python lives under
    # /tmp (a checkout there, as a CI clone may be), the folders that lead to them, nothing else.
    expected_tmp = {"home"} | {Path(path).resolve().relative_to("/tmp").parts[0]
                               for path in (KIT, sys.prefix, sys.base_prefix)
                               if Path(path).resolve().is_relative_to("/tmp")}
    kit = make_kit(tmp_path, textwrap.dedent(f"""
        checks = [
            os.path.exists({str(KIT / "instructor")!r}),  # the instructor's kit
            os.path.exists({str(KIT / "hwlib")!r}),
            os.path.exists({str(secret)!r}),  # the grader's own temporary files
            os.path.exists("/kit/hwlib/logreg.py"),  # the kit under test
            not set(os.listdir("/tmp")) <= set({sorted(expected_tmp)!r}),  # a fresh /tmp
            os.path.exists("/etc/passwd") or os.path.exists("/root/.ssh"),
        ]
        for path in ("/kit/hwlib/new.py", "/tmp/home/scratch"):  # no file is made, not even in its own /tmp
            try:
                open(path, "w").close()
                checks.append(True)
            except OSError:
                checks.append(False)
        values = np.array(checks, dtype=float)
    """))
    assert values(run(kit, isolated)).tolist() == [0, 0, 0, 1, 0, 0, 0, 0]


def test_unprivileged_in_its_own_process_namespace_with_a_clean_environment(isolated, tmp_path, monkeypatch):
    monkeypatch.setenv("HWGRADE_CANARY", "leaked")
    kit = make_kit(tmp_path, textwrap.dedent("""
        status = open("/proc/self/status").read()
        capabilities = int(status.split("CapEff:")[1].split()[0], 16)
        processes = [entry for entry in os.listdir("/proc") if entry.isdigit()]
        values = np.array([os.getuid(), capabilities, len(processes), "HWGRADE_CANARY" in os.environ], dtype=float)
    """))
    uid, capabilities, processes, canary = values(run(kit, isolated))
    assert uid == 65534 and capabilities == 0 and canary == 0
    assert processes < 10  # the host's processes are not visible


def environment_readout(paths):
    """Kit code that reads every process's environment and command line it can, as the environment
    read-out cheat does, and says whether the canary or one of ``paths`` appeared."""
    return textwrap.dedent(f"""
        seen = os.environ.copy().__repr__()
        for entry in os.listdir("/proc"):
            for name in ("environ", "cmdline"):
                try:
                    seen += open(f"/proc/{{entry}}/{{name}}", "rb").read().decode("utf-8", "replace")
                except OSError:
                    pass
        values = np.array([{CANARY!r} in seen] + [path in seen for path in {[str(p) for p in paths]!r}]
                          + [len(seen) > 0], dtype=float)
    """)


def test_bubblewrap_shows_the_sandbox_neither_the_grader_s_environment_nor_its_paths(isolated, tmp_path,
                                                                                      monkeypatch):
    monkeypatch.setenv(CANARY, "a token of the instructor's shell")
    # (the Python and its virtual environment are bound at their own paths: those show, nothing else)
    kit = make_kit(tmp_path, environment_readout([tmp_path, sandbox.WORKER, KIT / "hwlib", KIT / "instructor"]))
    canary, *paths, read = values(run(kit, isolated))
    assert read == 1 and canary == 0, "/proc/1/environ (bubblewrap's init) or another shows the grader's environment"
    assert paths == [0, 0, 0, 0], "a host path of the kit or the worker shows in the sandbox's /proc"
    box = Sandbox(python=sandbox.sys.executable, isolation="auto", time_limit=30)
    command, options = box.command(kit, 10)
    assert str(kit) not in " ".join(command) and str(kit) in " ".join(options)  # the paths go through a pipe


def test_the_user_sandbox_reads_no_environment_of_the_grader(user, tmp_path, monkeypatch):
    monkeypatch.setenv(CANARY, "a token of the instructor's shell")
    kit = make_kit(tmp_path, environment_readout([]))
    canary, read = values(run(kit, user))
    assert read == 1 and canary == 0


def test_the_user_sandbox_runs_as_a_user_of_its_own_on_a_kit_only_it_can_read(user, tmp_path):
    secret = make_kit(tmp_path / "a", "values = np.array([7.0])")
    (secret / "hwlib" / "reference.py").write_text("ANSWER = 42\n")
    other = user.start(secret)  # a run that holds its kit while the next one looks for it
    try:
        folder = other._run_folder
        kit = make_kit(tmp_path / "b", textwrap.dedent(f"""
            checks = [os.getuid() == 0, os.geteuid() == 0, {folder.uid} == os.getuid()]
            for path in ({str(folder.kit / "hwlib" / "reference.py")!r}, {str(folder.kit)!r}, {str(secret)!r}):
                try:
                    open(path).read() if path.endswith(".py") else os.listdir(path)
                    checks.append(True)
                except OSError:
                    checks.append(False)
            for path in ("/kit", os.path.dirname(os.path.dirname(__file__))):  # its own kit is read-only
                try:
                    open(os.path.join(path, "hwlib", "new.py"), "w").close()
                    checks.append(True)
                except OSError:
                    checks.append(False)
            status = open("/proc/self/status").read()
            checks.append(int(status.split("CapEff:")[1].split()[0], 16) != 0)
            checks.append(status.split("NoNewPrivs:")[1].split()[0] != "1")
            try:  # no file is made, not even in its own home
                open(os.path.join(os.environ["HOME"], "scratch"), "w").close()
                checks.append(True)
            except OSError:
                checks.append(False)
            values = np.array(checks, dtype=float)
        """))
        assert values(run(kit, user)).tolist() == [0] * 11
    finally:
        other.finish(graceful=False)
    assert not folder.base.exists(), "the run's folder is deleted after it"


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_memory_limit(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        try:
            hoard = np.ones(4 * 1024**3 // 8)  # 4 GiB
            values = np.array([1.0])
        except MemoryError:
            values = np.array([0.0])
    """))
    assert values(run(kit, box)).tolist() == [0.0]


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_endless_loop_ends_at_the_time_limit(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, "while True:\n    pass\nvalues = None")
    outcome, results = run(kit, box, time_limit=2)
    assert outcome.status in ("timeout", "ended") and not results
    assert outcome.status == "timeout" and "CPU-time limit" in outcome.detail, outcome


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_the_time_limit_counts_cpu_so_a_slow_machine_is_no_time_out(mode, request, tmp_path, monkeypatch):
    """Code that takes longer on the wall clock than its CPU limit (as on a loaded machine) is not
    timed out; code that waits for ever is, by the wall-clock backstop (here with 1 s of slack in place
    of WALL_SLACK's 10: the backstop is what is tested, not its size)."""
    box = request.getfixturevalue(mode)
    slow = make_kit(tmp_path / "slow", "time.sleep(2.5)\nvalues = np.array([1.0])")
    assert values(run(slow, box, time_limit=1)).tolist() == [1.0]
    stuck = make_kit(tmp_path / "stuck", "time.sleep(10_000)\nvalues = None")
    monkeypatch.setattr(sandbox, "WALL_SLACK", 1.0)
    outcome, _ = run(stuck, box, time_limit=0.1)
    assert outcome.status == "timeout" and "wall-clock" in outcome.detail, outcome
    assert outcome.seconds < 10, "stopped by the wall-clock backstop, not later"  # from the run's begin


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_a_child_that_holds_the_error_stream_does_not_hold_the_grader(mode, request, tmp_path):
    """A child that leaves the session and clears its environment (so that without a sandbox
    nothing finds it), keeping the worker's standard output and error open for CHILD_SECONDS."""
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent(f"""
        ready, written = os.pipe()
        if os.fork() == 0:
            leave_session()
            sys.stderr.write("the child holds stderr\\n")
            sys.stderr.flush()
            os.close(written)  # the parent answers once this line is written (the run is killed right after)
            os.execve("/bin/sleep", ["sleep", "{CHILD_SECONDS}.25"], {{}})
        os.close(written)
        os.read(ready, 1)
        values = np.array([1.0])
    """))
    holder = lambda: live_processes(lambda cmdline: cmdline == f"sleep\0{CHILD_SECONDS}.25\0".encode())  # noqa: E731
    try:
        ran = run(kit, box, time_limit=5)
        assert values(ran).tolist() == [1.0]
        outcome = ran[0]
        assert outcome.seconds < CHILD_SECONDS / 2, "the grader waited for the child"
        assert "the child holds stderr" in outcome.stderr_tail
        if mode != "plain":  # without a sandbox such a child outlives the run: docs/grading.md says so
            assert not holder(), "the child outlived the run"
    finally:
        for pid in holder():
            os.kill(pid, 9)


CHILD_SECONDS = 300


def worker_processes(kit, settle=3.0, before=frozenset()):
    """Live processes running the worker, in the sandbox (/grader/worker.py, or a grading's zygote,
    /grader/zygote.py, and every process it forks) or on ``kit`` without one, but those in
    ``before``; killed ones get up to ``settle`` seconds to go. (Workers this test process started
    earlier, a reference server of another test's grader, may still be alive: a test judges only
    the workers its own run started.)"""
    return live_processes(lambda cmdline: b"/grader/worker.py" in cmdline or b"/grader/zygote.py" in cmdline or
                          (b"worker.py" in cmdline and str(kit).encode() in cmdline), settle, before)


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_a_fork_does_not_outlive_the_run(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        if os.fork() == 0:
            leave_session()  # leaves the worker's session and process group
            if os.fork() == 0:
                while True:
                    time.sleep(0.05)
            os._exit(0)
        time.sleep(0.3)
        values = np.array([1.0])
    """))
    assert SUBREAPER, "the scan sees orphans only when this process reaps them"
    before = worker_processes(kit, settle=0)
    assert values(run(kit, box)).tolist() == [1.0]
    assert not worker_processes(kit, before=before), "a process started by the student's code outlived the run"


@pytest.mark.parametrize("mode", ["isolated", "user"])
def test_a_setsid_child_with_an_empty_environment_does_not_outlive_the_run(mode, request, tmp_path):
    """The Gradescope overwrite's first step: leave the session and exec with no environment
    (no token to find it by); the sandbox still ends it."""
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        if os.fork() == 0:
            leave_session()
            if os.fork() == 0:
                os.execve("/bin/sleep", ["sleep", "2999.5"], {})
            os._exit(0)
        time.sleep(0.3)
        values = np.array([1.0])
    """))
    sleeping = lambda: live_processes(lambda cmdline: cmdline == b"sleep\x002999.5\x00")  # noqa: E731
    assert values(run(kit, box)).tolist() == [1.0]
    assert not sleeping(), "a child with an empty environment outlived the run"


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_prints_and_exits_do_not_forge_answers(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        print("x" * 100000)
        sys.stdout.write("\\x00" * 16)
        if z[0] == 1:
            sys.exit(0)
        values = z + 1
    """))
    _, results = run(kit, box, cases=2)
    assert results["c0"]["status"] == "ok" and results["c0"]["values"]["values"].tolist() == [1.0]
    assert results["c1"]["status"] == "error" and results["c1"]["error"].startswith("SystemExit")


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_garbage_on_the_answer_channel_is_caught(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        for fd in range(3, 20):
            try:
                os.write(fd, b"\\xff" * 64)
            except OSError:
                pass
        values = z
    """))
    outcome, results = run(kit, box)
    assert outcome.status in ("garbled", "ended") or results["c0"]["values"]["values"].tolist() == [0.0]


def test_without_bubblewrap_the_grader_says_so(monkeypatch):
    sandbox.probe_isolation.cache_clear()
    user_sandbox.probe.cache_clear()
    monkeypatch.setattr(sandbox.shutil, "which", lambda name: None)
    try:
        box = Sandbox(python=sandbox.sys.executable, isolation="auto")
        assert not box.isolated and "bubblewrap" in box.how and box.kind == "none"
        with pytest.raises(RuntimeError, match="no sandbox"):
            Sandbox(python=sandbox.sys.executable, isolation="bwrap")
        with pytest.raises(RuntimeError, match="no sandbox"):
            Sandbox(python=sandbox.sys.executable, isolation="user")
    finally:
        sandbox.probe_isolation.cache_clear()
        user_sandbox.probe.cache_clear()


def test_where_bubblewrap_fails_as_in_docker_the_user_sandbox_takes_over(user_python, fake_bwrap, monkeypatch):
    monkeypatch.setenv("PATH", f"{fake_bwrap}:{os.environ['PATH']}")
    sandbox.probe_isolation.cache_clear()
    try:
        box = Sandbox(python=user_python, isolation="auto")
        assert box.kind == "user" and box.isolated, box.how
        assert "Creating new namespace failed: Operation not permitted" in box.how
    finally:
        sandbox.probe_isolation.cache_clear()


def test_killing_the_sandbox_users_spares_a_run_that_another_grader_holds(user, tmp_path):
    held = user.start(make_kit(tmp_path, "values = np.array([3.0])"))  # as another grader's run would
    try:
        uid = held._run_folder.uid
        # A user that no grader holds (a second test run may hold others): taken while its stray
        # starts, as a run would, and given back before the killing. (A run that takes it between
        # kills that user's processes first, the stray too.)
        slot = user_sandbox._Slot()
        free = slot.user
        try:
            stray = subprocess.Popen(["setpriv", f"--reuid={free.pw_uid}", f"--regid={free.pw_gid}", "--clear-groups",
                                      "--", "sleep", "2999.75"])
            while not user_sandbox.processes_of(free.pw_uid) and stray.poll() is None:
                time.sleep(0.05)
        finally:
            slot.release()
        assert user_sandbox.kill_all_users()
        assert stray.wait(timeout=30) == -9, "a free user's process survived"
        assert held.process.poll() is None and user_sandbox.processes_of(uid), "a held run was killed in its middle"
    finally:
        held.finish(graceful=False)
    assert not user_sandbox.processes_of(uid)


def test_a_trusted_run_under_the_user_fallback_takes_no_user_of_the_pool(user, tmp_path, monkeypatch):
    """A reference server (``trusted``: no student code) runs as the grader's own user: it never
    shares a uid with a student's run, and it never asks for a pool user, so it starts while
    students' runs hold every one (idle servers cannot starve the pool, nor a run wait for a server
    that waits for a user). Asking is refused here rather than tried by holding the whole pool,
    which a second test run on the machine shares."""
    pool = {entry.pw_uid for entry in user_sandbox.users()}
    asked = []

    class NoUserLeft:
        def __init__(self, *args, **kwargs):
            asked.append(args or kwargs)
            raise TimeoutError("every sandbox user stayed busy")

    monkeypatch.setattr(user_sandbox, "_Slot", NoUserLeft)
    with pytest.raises(TimeoutError):  # as a student's run would find it
        user.start(make_kit(tmp_path / "student", "values = np.array([1.0])"))
    assert asked
    asked.clear()
    server = user.start(make_kit(tmp_path / "server", "values = np.array([2.0])"), trusted=True)
    try:
        assert not asked, "a trusted run asked for a user of the pool"
        assert server._run_folder is None and real_uid(server.process.pid) == os.geteuid() not in pool
    finally:
        server.finish(graceful=False)


def test_the_grader_can_put_itself_under_a_memory_limit():
    code = ("from hwtools.grade.sandbox import limit_own_memory\n"
            "limit = limit_own_memory(2 * 1024**3)\n"
            "try:\n    hoard = bytearray(3 * 1024**3)\n    print(limit, 'allocated')\n"
            "except MemoryError:\n    print(limit, 'refused')\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=KIT)
    assert result.stdout.split() == [str(2 * 1024**3), "refused"], result.stderr


def test_messages_carry_numbers_only():
    message = {"cases": [{"id": "a", "args": {"x": np.arange(3.0), "n": 2, "name": "f"}}]}
    assert channel.unpack(channel.pack(message))["cases"][0]["args"]["n"] == 2
    with pytest.raises(TypeError):
        channel.pack({"x": np.array([object()], dtype=object)})
    buffer = io.BytesIO()
    np.savez(buffer, __json__=np.array('{"__array__": "a0"}'), a0=np.array([object()], dtype=object))
    with pytest.raises(ValueError):  # a pickled object array is refused, never unpickled
        channel.unpack(buffer.getvalue())
    assert channel.fingerprint(message) == channel.fingerprint({"cases": [{"id": "a", "args": {
        "x": np.arange(3.0), "n": 2, "name": "f"}}]})


def test_the_orphans_of_a_user_run_are_reaped_so_its_user_can_fork_again(user, tmp_path):
    """An orphan of a user-fallback run is killed at the run's end and, as this process is a
    subreaper, becomes this process's zombie of that user, which counts against the user's
    process limit until reaped (two test runs at once ran out of it: fork() gave EAGAIN)."""
    kit = make_kit(tmp_path, textwrap.dedent("""
        for _ in range(5):
            if os.fork() == 0:
                leave_session()
                if os.fork() == 0:
                    time.sleep(600)
                os._exit(0)
        time.sleep(0.3)
        values = np.array([1.0])
    """))
    assert values(run(kit, user)).tolist() == [1.0]
    deadline = time.monotonic() + 10
    while len(adopted_zombies()) < 5 and time.monotonic() < deadline:  # killed by the run's end, not yet reaped
        time.sleep(0.05)
    assert len(adopted_zombies()) >= 5
    assert reap_adopted_orphans() >= 5
    assert not adopted_zombies()


def at_once(box, kits_, budgets):
    """Runs of ``kits_`` started side by side (as a grader's threads start them), each with its grading's
    budget: their outcomes."""
    outcomes = [None] * len(kits_)

    def one(index):
        process = box.start(kits_[index], budget=budgets[index])
        outcomes[index] = broker.run_cases(process, None, [("c0", "sigmoid", {"z": np.array([0.0])})], [], None)

    threads = [threading.Thread(target=one, args=(index,)) for index in range(len(kits_))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    return outcomes


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_two_runs_of_one_grading_never_overlap(mode, request, tmp_path):
    """A grading's runs, started side by side (as a grader's threads start them), take its turn: the
    second one's code starts only after every process of the first one is gone (its child too), so
    no lock, inotify watch or shared timing can carry anything between two runs of one grading
    (docs/grading.md, what must still be ordered)."""
    box, grading = request.getfixturevalue(mode), sandbox.Budget(600)
    two = [make_kit(tmp_path / name, textwrap.dedent("""
        started = time.time()
        if os.fork() == 0:  # a child that would live on, holding a lock
            import fcntl
            fcntl.flock(os.open(sys.executable, os.O_RDONLY), fcntl.LOCK_SH)
            time.sleep(600)
        time.sleep(1.0)
        values = np.array([started, time.time()])
    """)) for name in ("a", "b")]
    (a_start, a_end), (b_start, b_end) = (values(outcome).tolist() for outcome in at_once(box, two, [grading] * 2))
    assert a_end <= b_start or b_end <= a_start, "two runs of one grading overlapped"


ZYGOTE_RUN = textwrap.dedent("""
    import hashlib, resource, signal
    others = [pid for pid in map(int, filter(str.isdigit, os.listdir("/proc"))) if pid not in (1, os.getpid())]
    descriptors = len(os.listdir("/proc/self/fd"))

    def refused(path, mode):
        try:
            open(path, mode).close()
            return 0.0
        except PermissionError:
            return 1.0

    values = np.array([{mine}, len(others), descriptors, refused("/proc/1/environ", "rb"), refused("/proc/1/mem", "r+b"),
                       float(int(hashlib.sha256(repr(sorted(os.environ.items())).encode()).hexdigest()[:12], 16)),
                       float(sorted(os.listdir("/kit")) == ["_hwgrade", "hwlib"] and
                             os.path.isdir("/kit/hwlib/extra") == {extra}),
                       np.random.random()] + [float(resource.getrlimit(getattr(resource, name))[0]) for name in
                                              ("RLIMIT_CPU", "RLIMIT_AS", "RLIMIT_FSIZE", "RLIMIT_NOFILE")])
    if os.fork() == 0:  # what a run leaves for the next one: a child, its environment, signals to the zygote
        time.sleep(600)
    os.environ["HWGRADE_LEFT"] = "1"
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGUSR1, signal.SIGSTOP, signal.SIGKILL):
        os.kill(1, number)
""")


def test_a_zygote_s_runs_begin_alone_and_inherit_nothing_of_each_other(isolated, zygote, tmp_path):
    """Three runs forked one after the other by one zygote (the first in one grading, the next two in
    the grading it serves next, as a grader's zygote serves its gradings in turn), each of which leaves a child
    behind, changes its environment and signals the zygote (SIGINT, SIGTERM, SIGHUP, SIGUSR1,
    SIGSTOP, SIGKILL): each begins with no process of the sandbox alive but itself and the zygote
    (PID 1), with the descriptors, environment and limits of a run in a sandbox of its own (its CPU
    limit its own, not the zygote's), its own draw of numpy's global generator, its own kit alone in
    ``/kit`` (the first one's extra folder gone), its own code (not the zygote's compiled template,
    ``TEMPLATE``), and cannot read or write the zygote's memory (non-dumpable)."""
    runs = [make_kit(tmp_path / str(index), ZYGOTE_RUN.format(mine=index, extra=index == 1)) for index in range(4)]
    (runs[1] / "hwlib" / "extra").mkdir()
    (runs[1] / "hwlib" / "extra" / "left.py").write_text("")
    alone = values(run(runs[0], isolated)).tolist()
    forked, first = [values(run(runs[1], zygote)).tolist()], zygote.grading.zygote
    zygote.grading.close()
    zygote.grading = sandbox.Budget(3600, zygote.zygotes.take(TEMPLATE))
    assert zygote.grading.zygote is first, "a later grading did not take the zygote left idle"
    forked += [values(run(kit, zygote)).tolist() for kit in runs[2:]]
    for index, seen in enumerate(forked, 1):
        assert seen[0] == index, "a run ran another run's code"
        assert seen[1] == 0, f"run {index} began beside {seen[1]:.0f} processes of the run before it"
        assert seen[2] <= alone[2], "a forked run holds descriptors that a run of its own does not"
        assert seen[3:5] == [1.0, 1.0], "a run could read or write the zygote's memory"
        assert seen[5:7] == alone[5:7] and seen[6] == 1.0, "a run's environment or kit was not its own"
        assert seen[8:] == alone[8:], "a forked run's limits are not those of a run"
    assert len({seen[7] for seen in forked}) == 3, "runs drew the same numbers from numpy's global generator"


def test_a_lost_zygote_fails_its_grading_s_later_runs(zygote, tmp_path):
    """Fail closed: once a grading's zygote is gone (killed from outside, as the kernel's OOM killer
    might), every later run of that grading fails, in fixed words, and none runs elsewhere; the
    next grading gets a zygote of its own. Nor is a later grading given a zygote that died while idle,
    or one while a run of its grading is still alive."""
    kit = make_kit(tmp_path, "values = np.array([1.0])")
    assert values(run(kit, zygote)).tolist() == [1.0]
    lost = zygote.grading.zygote
    signal.pidfd_send_signal(lost.process._init, signal.SIGKILL)
    for _ in range(2):
        outcome, results = run(kit, zygote)
        assert (outcome.status, outcome.detail, results) == ("lost", broker.STOPS["lost"], {})
    zygote.grading.close()
    zygote.grading = sandbox.Budget(3600, zygote.zygotes.take(TEMPLATE))
    assert zygote.grading.zygote is not lost and values(run(kit, zygote)).tolist() == [1.0]
    idle = zygote.grading.zygote
    zygote.grading.close()
    signal.pidfd_send_signal(idle.process._init, signal.SIGKILL)
    idle.process.process.wait(timeout=30)
    zygote.grading = sandbox.Budget(3600, zygote.zygotes.take(TEMPLATE))
    assert zygote.grading.zygote is not idle, "a grading was given a zygote that died while idle"
    busy, alive = zygote.grading.zygote, zygote.start(kit)
    alive.begin()  # forked: its processes live until its end
    zygote.grading.close()
    zygote.grading = sandbox.Budget(3600, zygote.zygotes.take(TEMPLATE))
    alive.finish(graceful=False)
    assert zygote.grading.zygote is not busy, "a zygote went to a later grading while a run of it was alive"


def test_the_runs_of_two_gradings_run_side_by_side(plain, tmp_path):
    """Two gradings (two submissions of a class, two grading processes) do not wait for each other:
    each of two runs, one per grading, sees the other one alive. What a channel
    between them could carry is worth nothing, since every grading draws its own hidden inputs
    (docs/grading.md); before, one run at a time on the whole machine kept every submission waiting."""
    marks = tmp_path / "marks"
    marks.mkdir()
    two = [make_kit(tmp_path / name, textwrap.dedent(f"""
        mine, other = {str(marks / name)!r}, {str(marks / ("b" if name == "a" else "a"))!r}
        open(mine, "w").close()
        end = time.time() + 30
        while not os.path.exists(other) and time.time() < end:
            time.sleep(0.01)
        values = np.array([float(os.path.exists(other))])
        time.sleep(0.2)
        os.unlink(mine)
    """)) for name in ("a", "b")]
    outcomes = at_once(plain, two, [sandbox.Budget(600), sandbox.Budget(600)])  # each grading's own turn
    assert [values(outcome).tolist() for outcome in outcomes] == [[1.0], [1.0]], "a grading waited for another"


def test_with_a_reference_and_no_sandbox_no_student_code_runs(monkeypatch, tmp_path):
    """Fail closed: where neither bubblewrap nor the user fallback works, a grader with a reference
    (points decided) refuses to run a submission, with the fix; only an explicit isolation="none"
    runs it (and says NOT ISOLATED), and the instructor's own kit still grades itself."""
    from hwtools.grade import Grader, GradingError, blocks
    from hwtools.grade.instructor import classroom

    marker = tmp_path / "ran"
    layout = blocks.load_layout(KIT)
    kits.write_submission(layout, tmp_path / "subs" / "alice", {"2.2.1": (
        f"open({str(marker)!r}, 'w').close()\nvalues = 1.0 / (1.0 + np.exp(-z))")}, others="reference")
    sandbox.probe_isolation.cache_clear()
    user_sandbox.probe.cache_clear()
    monkeypatch.setattr(sandbox.shutil, "which", lambda name: None)
    try:
        grader = Grader(KIT, time_limit=10)
        assert not grader.sandbox.isolated
        with pytest.raises(GradingError, match="no sandbox works here.*bubblewrap python3-seccomp.*--isolation none"):
            grader.grade(tmp_path / "subs" / "alice", todos=["2.2.1"])
        with pytest.raises(GradingError, match="no sandbox works here"):
            classroom.grade_class(tmp_path / "subs", tmp_path / "g.csv", tmp_path / "fb", grader=grader, jobs=1)
        assert not marker.exists(), "the submission's code ran without a sandbox"
        assert grader.grade(KIT, todos=["2.2.1"])["total"]["auto_earned"] == 2  # the instructor's own code
        explicit = Grader(KIT, time_limit=10, isolation="none").grade(tmp_path / "subs" / "alice", todos=["2.2.1"])
        assert marker.exists() and not explicit["isolated"]
    finally:
        sandbox.probe_isolation.cache_clear()
        user_sandbox.probe.cache_clear()


def test_the_reference_is_tried_as_each_pool_user_while_no_run_holds_that_user(user_python, monkeypatch):
    """The try runs as a pool user: a run of that user (another grading process's, beside it) could
    kill it (its end kills every process of the user), which counted the reference as readable and
    refused to grade (a CI run beside another), or answer for it. Each try holds its user first."""
    held, plain = [], user_sandbox.as_user

    def as_user(uid, gid, argv, timeout=None):
        name = next(entry.pw_name for entry in user_sandbox.users() if entry.pw_uid == uid)
        held.append(name in user_sandbox._HELD)
        return plain(uid, gid, argv, timeout)

    monkeypatch.setattr(user_sandbox, "as_user", as_user)
    user_sandbox.readable_by_pool([KIT / "instructor" / "hidden_checks" / "__init__.py"])
    assert held and all(held), held


def test_the_user_fallback_refuses_to_grade_while_a_pool_user_can_read_the_reference(user_python, tmp_path):
    """Checked as each pool user: a reference kit in a world-readable folder is refused, with the fix;
    the same kit behind a folder only root may enter is taken."""
    from hwtools.grade import Grader, GradingError

    folder = Path(tempfile.mkdtemp(prefix="hwgrade-readable-"))
    try:
        folder.chmod(0o755)
        shutil.copytree(KIT / "hwlib", folder / "kit" / "hwlib", ignore=shutil.ignore_patterns("__pycache__"))
        shutil.copytree(KIT / "instructor" / "hidden_checks", folder / "kit" / "instructor" / "hidden_checks",
                        ignore=shutil.ignore_patterns("__pycache__"))
        assert user_sandbox.readable_by_pool([folder / "kit" / "hwlib" / "logreg.py"])
        grader = Grader(folder / "kit", python=user_python, isolation="user")
        with pytest.raises(GradingError, match=r"sandbox's users can read the reference solution .*chmod o-rwx"):
            grader.grade(tmp_path, todos=["2.2.1"])
        assert grader.refusal(folder / "kit") is None  # the instructor's own kit may still grade itself
        (folder / "kit").chmod(0o750)
        assert not user_sandbox.readable_by_pool([folder / "kit" / "hwlib" / "logreg.py"])
        assert Grader(folder / "kit", python=user_python, isolation="user").refusal() is None
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_a_submission_s_runs_share_a_wall_clock_budget(isolated, tmp_path, monkeypatch):
    """An endless loop in every TODO: the runs take turns and spend the submission's budget
    (BUDGET_FACTOR x the time limit); once it is spent the remaining TODOs are not run and fail as
    timed out, so a submission costs at most the budget, not ten runs x the limit. Judged on each
    run's own clock (what was left at its begin, its deadline), never on the test's wall clock:
    waiting for the grading's turn or a loaded machine is not the submission's time."""
    from hwtools.grade import Grader, blocks, checks
    from hwtools.grade.grader import BUDGET_FACTOR

    runs = []  # per run of the submission that began: (budget left at its begin, its deadline - its start)
    plain_begin = sandbox.WorkerProcess.begin
    budget = BUDGET_FACTOR * 1

    def begin(worker):  # (the known mistakes' runs have a grading of their own, without a bound)
        first = worker.budget is not None and worker.budget.seconds == budget and not worker.begun
        try:
            plain_begin(worker)
        finally:  # the runs are one at a time: nothing else spends this budget while this one is on
            if first:
                runs.append((worker.budget.remaining(), worker.deadline - worker.started))

    layout = blocks.load_layout(KIT)
    kits.write_submission(layout, tmp_path / "loops", {todo: "while True:\n    pass" for todo in checks.GRADED_TODOS})
    with Grader(KIT, time_limit=1, jobs=2) as grader:
        grader.grade(KIT, todos=["2.2.1"])  # the reference's answers and servers first: not the submission's time
        monkeypatch.setattr(sandbox.WorkerProcess, "begin", begin)
        result = grader.grade(tmp_path / "loops")
    entries = [entry for entry in result["todos"] if entry["id"] in checks.GRADED_TODOS]
    assert all(entry["status"] == "time limit" for entry in entries), [(e["id"], e["status"]) for e in entries]
    spent = [entry["id"] for entry in entries if any("time budget was used up" in note for note in entry["notes"])]
    assert 1 <= len(entries) - len(spent) and len(spent) >= 2, spent  # the first runs ran, the last ones not at all
    assert runs and runs[0][0] == budget, runs  # the first run begins with the whole budget
    for left, limit in runs:  # each run may last only what the budget had left at its begin
        assert limit == pytest.approx(min(sandbox.wall_limit(1), max(left, 0.0))), runs
    ran = [left for left, _ in runs if left > 0]
    # the runs that ran to their own limit, then at most one cut short when the budget ran out;
    # every later one began with nothing left and was given no time at all (above)
    assert len(entries) - len(spent) <= len(ran) <= len(entries) - len(spent) + 1, runs
    assert all(later < earlier for earlier, later in zip(ran, ran[1:])), runs  # the runs spend one budget


def test_a_sweeper_that_stops_every_process_of_its_user_cannot_hold_the_grader(user, tmp_path):
    """A child of the student's code SIGSTOPs every other process of its user, as fast as it can:
    the process that kills the run's user at its end (once a fork of the grader that held its locks,
    waited for without a deadline) is caught too. The run still ends, every process of the user is
    killed by root, and the next run begins (no lock held by a stopped process)."""
    kit = make_kit(tmp_path / "sweeper", textwrap.dedent("""
        import signal
        worker = os.getpid()
        if os.fork() == 0:
            leave_session()
            while os.getppid() == worker:  # the run is over when the worker is gone
                time.sleep(0.001)
            while True:  # one system call stops every other process of the user
                try:
                    os.kill(-1, signal.SIGSTOP)
                except OSError:
                    pass
        time.sleep(0.3)
        values = np.array([1.0])
    """))
    done, before = [], worker_processes(kit, settle=0)
    thread = threading.Thread(target=lambda: done.append(run(kit, user)), daemon=True)
    thread.start()
    thread.join(timeout=240)
    assert done, "the grader was held by a stopped process"
    assert values(done[0]).tolist() == [1.0]
    assert not worker_processes(kit, before=before), "the sweeper outlived the run"
    nxt = make_kit(tmp_path / "next", "values = np.array([2.0])")
    assert values(run(nxt, user)).tolist() == [2.0]


def test_a_kill_as_the_run_s_user_that_is_stopped_is_ended_by_root(user, monkeypatch):
    """The sweeper's catch made certain: the process that kills as the run's user stops before it
    acts. The grader waits for it KILL_SECONDS at most, ends it with SIGKILL from root and kills the
    user's processes itself; nothing of the user is left, the stopped process included."""
    monkeypatch.setattr(user_sandbox, "KILL", ("/bin/sh", "-c", "kill -STOP $$"))
    monkeypatch.setattr(user_sandbox, "KILL_SECONDS", 2.0)
    slot = user_sandbox._Slot()
    try:
        uid, gid = slot.user.pw_uid, slot.user.pw_gid
        stray = subprocess.Popen(["setpriv", f"--reuid={uid}", f"--regid={gid}", "--clear-groups", "--",
                                  "sleep", "2999.5"])
        while not user_sandbox.processes_of(uid) and stray.poll() is None:
            time.sleep(0.05)
        done = []
        thread = threading.Thread(target=lambda: done.append(user_sandbox.kill_user(uid, gid)), daemon=True)
        thread.start()
        thread.join(timeout=120)
        assert done == [True], "the grader waited for a stopped process"
        assert stray.wait(timeout=30) == -9
        assert not user_sandbox.processes_of(uid)
    finally:
        slot.release()


ATTACKS = ("file", "folder", "symlink", "fifo", "socket file", "unnamed file", "memory file", "preallocated",
           "socket pair", "namespace", "shared memory", "bigger pipe", "byte-range lock", "file watch",
           "session of its own")
MAKE_EVERYTHING = textwrap.dedent("""
    import ctypes, fcntl, socket, stat
    libc = ctypes.CDLL(None, use_errno=True)
    libc.shmget.argtypes = (ctypes.c_int, ctypes.c_size_t, ctypes.c_int)
    libc.fallocate.argtypes = (ctypes.c_int, ctypes.c_int, ctypes.c_long, ctypes.c_long)

    def call(result):
        if result < 0:
            raise OSError(ctypes.get_errno(), "refused")

    made, token, tries = dict.fromkeys({attacks!r}, 0), {token!r}, {tries}

    def attempt(kind, action, tries=1):
        for number in range(tries):
            try:
                action(number)
            except OSError:
                return
            made[kind] += 1

    for place in {{"/tmp", "/var/tmp", "/dev/shm", "/run/lock", os.environ["HOME"], os.getcwd()}}:
        if not os.access(place, os.W_OK):
            continue
        name = os.path.join(place, token)
        attempt("file", lambda n: open(f"{{name}}-file{{n}}", "w").close(), tries)
        attempt("folder", lambda n: os.mkdir(f"{{name}}-folder{{n}}"), tries)
        attempt("symlink", lambda n: os.symlink("x" * 4000, f"{{name}}-link{{n}}"), tries)
        attempt("fifo", lambda n: os.mkfifo(f"{{name}}-fifo{{n}}"), tries)
        attempt("socket file", lambda n: os.mknod(f"{{name}}-socket{{n}}", stat.S_IFSOCK | 0o600), tries)
        attempt("unnamed file", lambda n: os.open(place, os.O_TMPFILE | os.O_WRONLY))  # a deleted file held open
    attempt("memory file", lambda n: os.memfd_create("hoard"))
    # space past the file-size limit, in the run's error stream (a file of the grader's): KEEP_SIZE
    attempt("preallocated", lambda n: call(libc.fallocate(2, 1, 0, {preallocated})))
    attempt("socket pair", lambda n: socket.socketpair())  # for descriptors in flight (SCM_RIGHTS)
    attempt("namespace", lambda n: call(libc.unshare(0x10000000 | 0x00020000)))  # a user and mount namespace
    attempt("shared memory", lambda n: call(libc.shmget(0, 64 * 1024**2, 0o600)))
    attempt("bigger pipe", lambda n: fcntl.fcntl(os.pipe()[1], 1031, 1024**2))  # F_SETPIPE_SZ
    held = os.open(sys.executable, os.O_RDONLY)
    attempt("byte-range lock", lambda n: fcntl.lockf(held, fcntl.LOCK_SH, 1, 2 * n), tries)  # each one kernel memory
    attempt("file watch", lambda n: call(libc.inotify_add_watch(libc.inotify_init(), b"/usr", 1)))

    def new_session(n):  # a child's: the worker leads its session already
        child = os.fork()
        if child == 0:
            try:
                os.setsid()
                os._exit(0)
            except OSError:
                os._exit(1)
        if os.waitpid(child, 0)[1]:
            raise OSError("refused")
    attempt("session of its own", new_session)  # a share of the CPU of its own (the scheduler's autogroup)
    values = np.array([made[kind] for kind in {attacks!r}], dtype=float)
""")


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user"])
def test_a_run_makes_no_file_no_socket_and_no_namespace(mode, request, tmp_path):
    """Every kind of file (regular, folder, symlink, fifo, socket, an unnamed one held open), in every
    place the run may write, tries times each (symlinks of 4,000 bytes: 262,144 once took 1 GiB under
    the user fallback, whose 0.25 s poll counted regular files only), preallocated space past the
    file-size limit, a memory file, descriptors to pass on a socket pair, a namespace of its own
    (where a nested one mounted a tmpfs of 1.5 GiB), System V shared memory, a pipe of 1 MiB,
    byte-range locks, a watch on a folder and a child in a session of its own: the kernel refuses each (the seccomp filter, ``confine.py``), so the run holds no disk and no such
    memory at any moment and leaves nothing."""
    box = request.getfixturevalue(mode)
    token, tries = f"hwgrade-made-{os.getpid()}-{time.monotonic_ns()}", 100
    kit = make_kit(tmp_path, MAKE_EVERYTHING.format(attacks=ATTACKS, token=token, tries=tries,
                                                    preallocated=2 * sandbox.MAX_FILE_BYTES))
    made = dict(zip(ATTACKS, values(run(kit, box)).tolist()))
    left = [path for place in ("/tmp", "/var/tmp", "/dev/shm", "/run/lock") for path in Path(place).glob(f"{token}*")]
    for path in left:
        shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
    assert not {kind: count for kind, count in made.items() if count}, f"made: {made}"
    assert not left, "a run's files outlived it"


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user", "plain"])
def test_every_process_of_a_run_has_an_open_file_limit(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, "import resource\nvalues = np.array(resource.getrlimit(resource.RLIMIT_NOFILE), dtype=float)")
    assert values(run(kit, box)).tolist() == [sandbox.MAX_OPEN_FILES] * 2


PIPE_BYTES = 16 * 4096  # a pipe's default buffer: 16 pages


@pytest.mark.parametrize("mode", ["isolated", "user"])
def test_without_a_cgroup_the_memory_a_run_holds_in_pipes_is_bounded(mode, request, monkeypatch, tmp_path):
    """Pipe buffers are memory outside every process's address space (1.5 GiB was once held so). A
    run forks as many children as it may, each fills as many pipes as it may open, each made as big
    as it may (F_SETPIPE_SZ), and keeps their read ends, aiming at 10 times the bound: it holds at
    most MAX_PROCESSES x MAX_OPEN_FILES pipes of 16 pages, whatever the host's soft limit on a
    user's pipe pages."""
    box = request.getfixturevalue(mode)
    if box.kind == "bwrap" and os.geteuid() != 0:
        pytest.skip("a bubblewrap grader that is not root has no process limit of the run's own (docs/grading.md)")
    monkeypatch.setattr(cgroups.RunGroup, "make", classmethod(lambda cls, *args, **kwargs: None))
    bound = cgroups.MAX_PROCESSES * sandbox.MAX_OPEN_FILES * PIPE_BYTES
    kit = make_kit(tmp_path, textwrap.dedent(f"""
        import fcntl, mmap
        shares = np.frombuffer(mmap.mmap(-1, 8 * 200), dtype=np.int64)  # the bytes each child holds
        done = np.frombuffer(mmap.mmap(-1, 200), dtype=np.int8)
        share, children = {10 * bound} // {cgroups.MAX_PROCESSES}, 0
        for child in range(1, 200):
            try:
                pid = os.fork()
            except OSError:
                break
            if pid:
                children += 1
                continue
            held = []
            try:
                while shares[child] < share:
                    read, write = os.pipe()
                    os.set_blocking(write, False)
                    try:
                        fcntl.fcntl(write, 1031, 1024**2)
                    except OSError:
                        pass
                    try:
                        while shares[child] < share:
                            shares[child] += os.write(write, bytes(4096))
                    except BlockingIOError:
                        pass
                    os.close(write)
                    held.append(read)
            except OSError:
                pass
            done[child] = 1
            time.sleep(120)
            os._exit(0)
        while done.sum() < children:
            time.sleep(0.05)
        values = np.array([float(shares.sum()), children])
    """))
    held, children = values(run(kit, box)).tolist()
    assert children >= cgroups.MAX_PROCESSES // 2, children  # the attack did spread over many processes
    assert held <= bound, f"{held / 2**20:.0f} MiB held in pipes (bound {bound / 2**20:.0f} MiB)"


def test_bubblewrap_s_writable_places_are_its_own_size_limited_tmpfs(isolated, tmp_path):
    """The only folders a bubblewrap run may write to are its own tmpfs mounts (gone with it): /tmp
    and /dev/shm, of TMPFS_BYTES and SHM_BYTES as the kernel reports them (``--size``: this
    bubblewrap has it); the sandbox's root (a tmpfs without a size limit that holds the mount points)
    and the rest of /dev are read-only (/dev/pts holds no files). It makes no file there either
    (test_a_run_makes_no_file_no_socket_and_no_namespace)."""
    if isolated.kind != "bwrap":
        pytest.skip("bubblewrap does not work here")
    kit = make_kit(tmp_path, textwrap.dedent("""
        writable = []
        for folder, names, _ in os.walk("/"):
            if folder == "/proc":
                names[:] = []
            elif os.access(folder, os.W_OK) and not folder.startswith(("/tmp", "/dev/shm", "/dev/pts")):
                writable.append(folder)
        if writable:
            raise RuntimeError("writable: " + " ".join(writable))
        sizes = [os.statvfs(place) for place in ("/tmp", "/dev/shm")]
        values = np.array([size.f_blocks * size.f_frsize for size in sizes], dtype=float)
    """))
    assert values(run(kit, isolated)).tolist() == [bwrap_sandbox.TMPFS_BYTES, bwrap_sandbox.SHM_BYTES]


def test_without_prlimit_neither_sandbox_works(user_python, monkeypatch):
    """Fail closed: without util-linux's prlimit a run's limits (processes, file size, open files)
    cannot be set, so neither sandbox is used (and a grader with a reference runs no submission)."""
    which = shutil.which
    monkeypatch.setattr(shutil, "which", lambda name, *args, **kwargs: None if name == "prlimit" else
                        which(name, *args, **kwargs))
    sandbox.probe_isolation.cache_clear()
    user_sandbox.probe.cache_clear()
    try:
        for isolation in ("bwrap", "user"):
            with pytest.raises(RuntimeError, match="no sandbox: prlimit .*missing"):
                Sandbox(python=user_python, isolation=isolation)
    finally:
        sandbox.probe_isolation.cache_clear()
        user_sandbox.probe.cache_clear()


def test_without_the_seccomp_filter_no_student_code_runs(monkeypatch, tmp_path):
    """Fail closed: where the filter cannot be compiled or loaded (the system's Python has no
    python3-seccomp), neither sandbox works, so a grader with a reference runs no submission, and
    says how to fix the machine."""
    from hwtools.grade import Grader, GradingError

    sandbox.probe_isolation.cache_clear()
    user_sandbox.probe.cache_clear()
    bwrap_sandbox.seccomp_program.cache_clear()
    for module in (bwrap_sandbox, user_sandbox):
        monkeypatch.setattr(module, "SYSTEM_PYTHON", sys.executable)  # a Python without the seccomp module
    try:
        with pytest.raises(RuntimeError, match="no sandbox: .*apt-get install python3-seccomp"):
            Sandbox(python=sys.executable, isolation="bwrap")
        grader = Grader(KIT, time_limit=10)
        assert not grader.sandbox.isolated
        with pytest.raises(GradingError, match="no sandbox works here.*python3-seccomp"):
            grader.grade(tmp_path, todos=["2.2.1"])
    finally:
        sandbox.probe_isolation.cache_clear()
        user_sandbox.probe.cache_clear()
        bwrap_sandbox.seccomp_program.cache_clear()


@pytest.mark.parametrize("group", ["cgroup", "no cgroup"])
@pytest.mark.parametrize("mode", ["isolated", "user"])
def test_a_run_s_processes_are_bounded_as_a_whole(mode, group, request, monkeypatch, tmp_path):
    """A run that forks sleeping children until it cannot (at most 200 tried) gets fewer than
    MAX_PROCESSES of them: the run's cgroup (pids.max), else its process limit (RLIMIT_NPROC: the
    user fallback's user; a root grader's bubblewrap sandbox, counted in its own user namespace)."""
    box = request.getfixturevalue(mode)
    if group == "no cgroup":
        monkeypatch.setattr(cgroups.RunGroup, "make", classmethod(lambda cls, *args, **kwargs: None))
    elif cgroups.RunGroup.make(box.memory_limit) is None:
        pytest.skip("no cgroup here")
    if box.kind == "bwrap" and os.geteuid() != 0:
        pytest.skip("a bubblewrap grader that is not root has no process limit of the run's own (docs/grading.md)")
    kit = make_kit(tmp_path, textwrap.dedent("""
        children = 0
        for _ in range(200):
            try:
                pid = os.fork()
            except OSError:
                break
            if pid == 0:
                time.sleep(60)
                os._exit(0)
            children += 1
        values = np.array([float(children)])
    """))
    assert values(run(kit, box)).tolist()[0] < cgroups.MAX_PROCESSES


@pytest.mark.parametrize("mode", ["isolated", "zygote", "user"])
def test_a_run_s_memory_is_bounded_as_a_whole(mode, request, tmp_path):
    """Four children of 400 MiB each (every one under the 1 GiB per-process limit) do not all live
    at once: the run's cgroup holds the whole run, tmpfs files included, to its memory limit."""
    box = request.getfixturevalue(mode)
    if cgroups.RunGroup.make(box.memory_limit) is None:
        pytest.skip("no cgroup here: the memory limit is per process (docs/grading.md)")
    kit = make_kit(tmp_path, textwrap.dedent("""
        import mmap
        hoarding, children = np.frombuffer(mmap.mmap(-1, 4), dtype=np.int8), {}  # shared: each child's flag
        for number in range(4):
            pid = os.fork()
            if pid == 0:
                hoard = np.ones(400 * 1024**2 // 8)
                hoarding[number] = 1
                time.sleep(60)
                os._exit(0)
            children[pid] = number
        alive = dict.fromkeys(children, True)
        give_up = time.monotonic() + 20
        while time.monotonic() < give_up:
            for pid in [pid for pid in alive if alive[pid]]:
                if os.waitpid(pid, os.WNOHANG) != (0, 0):
                    alive[pid] = False  # killed
            holding = [pid for pid in alive if alive[pid] and hoarding[children[pid]]]
            if len(holding) == sum(alive.values()):
                break  # every living child holds its 400 MiB
            time.sleep(0.1)
        values = np.array([float(len(holding))])
    """))
    worker = box.start(kit)
    outcome, results = broker.run_cases(worker, None, [("c0", "sigmoid", {"z": np.array([0.0])})], [], None)
    held = values((outcome, results)).tolist()[0]
    assert held * 400 * 1024**2 < box.memory_limit, f"{held:.0f} children of 400 MiB lived at once"
    assert worker.memory_peak is not None and worker.memory_peak <= box.memory_limit
