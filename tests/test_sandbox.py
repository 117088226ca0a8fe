"""The sandbox the grader runs students' code in: what the code can see and do, and the limits.

Each test runs the worker on a tiny kit whose ``sigmoid`` does what the test needs (try the
network, look for the instructor's files, allocate memory...) and returns numbers saying what
happened. Tests of the isolation itself skip where bubblewrap cannot run (the grader then says
NOT ISOLATED); the limits hold either way.
"""

from __future__ import annotations

import io
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hwtools.grade import sandbox, worker
from hwtools.grade.sandbox import Sandbox
from process_watch import live_processes

KIT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.timeout(300)


def make_kit(folder, body):
    """A kit whose hwlib.logreg.sigmoid(z) runs ``body`` (which sets ``values``)."""
    package = folder / "kit" / "hwlib"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    code = "import os, sys, time\nimport numpy as np\n\n\ndef sigmoid(z):\n" + textwrap.indent(body, "    ") + \
        "\n    return values\n"
    (package / "logreg.py").write_text(code)
    return folder / "kit"


def run(kit, box, cases=1, time_limit=None):
    request = {"cases": [{"id": f"c{i}", "probe": "sigmoid", "args": {"z": np.array([float(i)])}} for i in range(cases)]}
    return box.run(kit, [request], time_limit)


def values(outcome):
    assert outcome.status == "ok", (outcome.status, outcome.detail, outcome.stderr_tail)
    result = outcome.answers[0]["results"][0]
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


def test_no_network(isolated, tmp_path):
    kit = make_kit(tmp_path, textwrap.dedent("""
        import socket
        try:
            socket.create_connection(("1.1.1.1", 53), timeout=3).close()
            values = np.array([1.0])
        except OSError:
            values = np.array([0.0])
    """))
    assert values(run(kit, isolated)).tolist() == [0.0]


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
        try:
            open("/kit/hwlib/new.py", "w").close()
            checks.append(True)
        except OSError:
            checks.append(False)
        with open("/tmp/home/scratch", "w") as handle:  # the private /tmp is writable
            handle.write("x")
        values = np.array(checks, dtype=float)
    """))
    assert values(run(kit, isolated)).tolist() == [0, 0, 0, 1, 0, 0, 0]
    assert values(run(kit, isolated)).tolist() == [0, 0, 0, 1, 0, 0, 0]  # the scratch file did not survive


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


@pytest.mark.parametrize("mode", ["isolated", "plain"])
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


@pytest.mark.parametrize("mode", ["isolated", "plain"])
def test_endless_loop_ends_at_the_time_limit(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, "while True:\n    pass\nvalues = None")
    outcome = run(kit, box, time_limit=2)
    assert outcome.status in ("timeout", "ended") and not outcome.answers


def worker_processes(kit, settle=3.0):
    """Live processes running the worker, in the sandbox (/grader/worker.py) or on ``kit`` without
    one; killed ones get up to ``settle`` seconds to go."""
    return live_processes(lambda cmdline: b"/grader/worker.py" in cmdline or
                          (b"worker.py" in cmdline and str(kit).encode() in cmdline), settle)


@pytest.mark.parametrize("mode", ["isolated", "plain"])
def test_a_fork_does_not_outlive_the_run(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        if os.fork() == 0:
            os.setsid()  # leaves the worker's session and process group
            if os.fork() == 0:
                while True:
                    time.sleep(0.05)
            os._exit(0)
        time.sleep(0.3)
        values = np.array([1.0])
    """))
    assert not worker_processes(kit, settle=0)
    assert values(run(kit, box)).tolist() == [1.0]
    assert not worker_processes(kit), "a process started by the student's code outlived the run"


@pytest.mark.parametrize("mode", ["isolated", "plain"])
def test_prints_and_exits_do_not_forge_answers(mode, request, tmp_path):
    box = request.getfixturevalue(mode)
    kit = make_kit(tmp_path, textwrap.dedent("""
        print("x" * 100000)
        sys.stdout.write("\\x00" * 16)
        if z[0] == 1:
            sys.exit(0)
        values = z + 1
    """))
    outcome = run(kit, box, cases=2)
    results = outcome.answers[0]["results"]
    assert results[0]["status"] == "ok" and results[0]["values"]["values"].tolist() == [1.0]
    assert results[1]["status"] == "error" and results[1]["error"].startswith("SystemExit")


@pytest.mark.parametrize("mode", ["isolated", "plain"])
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
    outcome = run(kit, box)
    assert outcome.status in ("garbled", "ended") or outcome.answers[0]["results"][0]["values"]["values"].tolist() == [0.0]


def test_without_bubblewrap_the_grader_says_so(monkeypatch):
    sandbox.probe_isolation.cache_clear()
    monkeypatch.setattr(sandbox.shutil, "which", lambda name: None)
    try:
        box = Sandbox(python=sandbox.sys.executable, isolation="auto")
        assert not box.isolated and "bubblewrap" in box.how
        with pytest.raises(RuntimeError, match="no sandbox"):
            Sandbox(python=sandbox.sys.executable, isolation="bwrap")
    finally:
        sandbox.probe_isolation.cache_clear()


def test_messages_carry_numbers_only():
    message = {"cases": [{"id": "a", "args": {"x": np.arange(3.0), "n": 2, "name": "f"}}]}
    assert worker.unpack(worker.pack(message))["cases"][0]["args"]["n"] == 2
    with pytest.raises(TypeError):
        worker.pack({"x": np.array([object()], dtype=object)})
    buffer = io.BytesIO()
    np.savez(buffer, __json__=np.array('{"__array__": "a0"}'), a0=np.array([object()], dtype=object))
    with pytest.raises(ValueError):  # a pickled object array is refused, never unpickled
        worker.unpack(buffer.getvalue())
    assert worker.fingerprint(message) == worker.fingerprint({"cases": [{"id": "a", "args": {
        "x": np.arange(3.0), "n": 2, "name": "f"}}]})
