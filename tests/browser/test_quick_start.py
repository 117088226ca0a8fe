"""The README's quick start does what it says, whatever its prose: its first two shell commands are the
quick start; the first installs the kit and starts JupyterLab on the kit's folder with the first notebook
open (so ``hwlib/`` is in its file browser), and the second is the test command that ``.ci/run`` runs,
verbatim.

The first command's ``jupyter lab`` part is started as written (plus what a test needs: no
browser, a free port, a token, private runtime folders), from the kit's folder; the test reads
the address the server would open and the folder it serves.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shlex
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from lab_under_test import free_port

KIT = Path(__file__).resolve().parents[2]


def shell_commands(markdown):
    """The commands of a Markdown text's shell code blocks (bash, sh, shell), one per line, in order."""
    blocks = re.findall(r"^```(?:bash|sh|shell)[ \t]*\n(.*?)^```", markdown, re.S | re.M)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def quick_start_commands():
    """The README's first two shell commands: install and start, then test."""
    return shell_commands((KIT / "README.md").read_text(encoding="utf-8"))[:2]


def ci_test_command():
    """The command .ci/run ends with: the one that runs the tests."""
    lines = [line.strip() for line in (KIT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    return [line for line in lines if line and not line.startswith("#")][-1]


def test_the_quick_start_is_two_commands_and_ci_runs_the_second():
    install_and_run, test = quick_start_commands()
    assert "pip install -r requirements.txt" in install_and_run and "jupyter lab" in install_and_run
    assert install_and_run.index("pip install") < install_and_run.index("jupyter lab")  # one command: install, then start
    assert re.search(r"\bpython -m pytest\b", test), test
    assert ci_test_command() == test, f".ci/run ends with {ci_test_command()!r}, not the README's {test!r}"


def test_the_quick_start_serves_the_kits_folder_with_the_first_notebook_open(tmp_path):
    install_and_run = quick_start_commands()[0]
    lab_args = shlex.split(install_and_run.split("jupyter lab", 1)[1])
    port, token = free_port(), secrets.token_hex(16)
    runtime = tmp_path / "runtime"
    env = {**os.environ, "JUPYTER_RUNTIME_DIR": str(runtime), "JUPYTER_CONFIG_DIR": str(tmp_path / "config"),
           "JUPYTER_DATA_DIR": str(tmp_path / "data"), "JUPYTER_PLATFORM_DIRS": "1"}
    command = [sys.executable, "-m", "jupyter", "lab", *lab_args, "--no-browser", "--allow-root",
               f"--ServerApp.port={port}", "--ServerApp.port_retries=0", "--ServerApp.ip=127.0.0.1",
               f"--IdentityProvider.token={token}", "--ServerApp.terminals_enabled=False",
               "--LabApp.news_url=None", "--LabApp.extension_manager=readonly"]
    server = subprocess.Popen(command, cwd=KIT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline, listing, opened = time.monotonic() + 90, None, None
        while time.monotonic() < deadline and (listing is None or opened is None):
            assert server.poll() is None, "jupyter lab exited"
            try:
                request = urllib.request.Request(f"http://127.0.0.1:{port}/api/contents",
                                                 headers={"Authorization": f"token {token}"})
                with urllib.request.urlopen(request, timeout=5) as response:
                    listing = json.load(response)
            except OSError:
                time.sleep(0.5)
                continue
            pages = list(runtime.glob("jpserver-file-to-run-*-open.html"))
            opened = pages[0].read_text() if pages else None
            time.sleep(0.2)
        assert listing is not None, "the server did not answer"
        names = {item["name"] for item in listing["content"]}
        assert {"hwlib", "notebooks", "README.md"} <= names, f"the server's root is not the kit's folder: {sorted(names)}"
        assert opened is not None, "the server opens no notebook"
        assert "/lab/tree/notebooks/p1_cartpole_finite_difference.ipynb" in opened
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        try:
            server.wait(15)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
