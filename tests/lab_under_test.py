"""A throwaway JupyterLab server for the browser test, and the Chromium it is driven with.

(Named so as not to shadow the ``jupyter_server`` and ``jupyterlab_server`` packages.)

``running_jupyterlab(root_dir, tmp_dir)`` starts JupyterLab from the test's own Python
environment (``sys.executable -m jupyter lab``) on a free port of 127.0.0.1 with a random token,
with its config, runtime, settings and workspace folders inside ``tmp_dir`` so nothing leaks
between runs, waits until it answers, and on the way out, however the ``with`` block ends,
shuts down its kernels, stops the server (SIGTERM, then SIGKILL after a timeout), kills any of
its processes that are left (kernels included) and checks that the port is free again.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

# Debian's Chromium and the flags it is started with: one definition, shared with the report's PDF.
from hwtools.report import CHROMIUM_ARGS, chromium_path  # noqa: F401

STARTUP_TIMEOUT = 60  # seconds until the server must answer
SHUTDOWN_TIMEOUT = 15  # seconds the server gets to stop after SIGTERM

# JupyterLab user settings written before the start: no news/update toasts, every cell kept in the
# DOM (no virtual scrolling), and no autosave writing the notebook back into the kit.
LAB_SETTINGS = {
    "@jupyterlab/apputils-extension/notification.jupyterlab-settings": {
        "fetchNews": "false",
        "checkForUpdates": False,
        "doNotDisturbMode": True,
    },
    "@jupyterlab/notebook-extension/tracker.jupyterlab-settings": {"windowingMode": "none"},
    "@jupyterlab/docmanager-extension/plugin.jupyterlab-settings": {"autosave": False},
}


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def port_in_use(port):
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.settimeout(1)
        return sock.connect_ex(("127.0.0.1", port)) == 0


@dataclass
class JupyterLab:
    process: subprocess.Popen
    port: int
    token: str
    root_dir: Path
    log_path: Path

    @property
    def base_url(self):
        return f"http://127.0.0.1:{self.port}"

    def url(self, path):
        """The browser URL of ``path`` (relative to the root dir) in a fresh JupyterLab workspace."""
        return f"{self.base_url}/lab/tree/{Path(path).as_posix()}?reset&token={self.token}"

    def api(self, method, path):
        request = urllib.request.Request(
            f"{self.base_url}{path}", method=method, headers={"Authorization": f"token {self.token}"}
        )
        with urllib.request.urlopen(request, timeout=10) as response:
            body = response.read()
        return json.loads(body) if body else None

    def log(self):
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""


def _children(pid):
    """Pids of the live child processes of ``pid`` (Linux /proc; empty elsewhere)."""
    children = []
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
        if int(fields[1]) == pid:
            children.append(int(entry.name))
    return children


def descendants(pid):
    found, todo = [], [pid]
    while todo:
        for child in _children(todo.pop()):
            found.append(child)
            todo.append(child)
    return found


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie is dead for our purposes
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


def _wait_until_answers(lab, deadline):
    while time.monotonic() < deadline:
        if lab.process.poll() is not None:
            raise RuntimeError(f"JupyterLab exited with code {lab.process.returncode} while starting:\n{lab.log()}")
        try:
            lab.api("GET", "/api/status")
            return
        except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
            time.sleep(0.3)
    raise TimeoutError(f"JupyterLab did not answer on port {lab.port} within {STARTUP_TIMEOUT} s:\n{lab.log()}")


def _stop(lab):
    """Shut the kernels down, stop the server, kill whatever of it is left; return the pids still alive."""
    process = lab.process
    if process.poll() is None:
        with contextlib.suppress(Exception):
            for kernel in lab.api("GET", "/api/kernels") or []:
                with contextlib.suppress(Exception):
                    lab.api("DELETE", f"/api/kernels/{kernel['id']}")
    # Kernels run in sessions of their own: remember every process the server started.
    spawned = descendants(process.pid) if process.poll() is None else []
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(SHUTDOWN_TIMEOUT)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.wait(10)
    for pid in spawned:
        if _alive(pid):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and any(_alive(pid) for pid in spawned):
        time.sleep(0.1)
    return [pid for pid in spawned if _alive(pid)]


@contextlib.contextmanager
def running_jupyterlab(root_dir, tmp_dir):
    """Start JupyterLab serving ``root_dir``; yield a ``JupyterLab``; always stop it."""
    root_dir, tmp_dir = Path(root_dir), Path(tmp_dir)
    dirs = {name: tmp_dir / name for name in ("config", "data", "runtime", "settings", "workspaces")}
    for path in dirs.values():
        path.mkdir(parents=True, exist_ok=True)
    for name, settings in LAB_SETTINGS.items():
        target = dirs["settings"] / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(settings))
    token = secrets.token_hex(24)
    port = free_port()
    env = {
        **os.environ,
        "JUPYTER_CONFIG_DIR": str(dirs["config"]),
        "JUPYTER_DATA_DIR": str(dirs["data"]),
        "JUPYTER_RUNTIME_DIR": str(dirs["runtime"]),
        "JUPYTERLAB_SETTINGS_DIR": str(dirs["settings"]),
        "JUPYTERLAB_WORKSPACES_DIR": str(dirs["workspaces"]),
        "JUPYTER_PLATFORM_DIRS": "1",
    }
    # As a student's kernel: no MPLBACKEND (the tests' Agg), so figures show inline.
    for name in ("JUPYTER_PATH", "MPLBACKEND"):
        env.pop(name, None)
    command = [
        sys.executable, "-m", "jupyter", "lab",
        "--no-browser",
        "--ServerApp.ip=127.0.0.1",
        f"--ServerApp.port={port}",
        "--ServerApp.port_retries=0",
        f"--IdentityProvider.token={token}",
        f"--ServerApp.root_dir={root_dir}",
        f"--LabApp.user_settings_dir={dirs['settings']}",
        f"--LabApp.workspaces_dir={dirs['workspaces']}",
        "--LabApp.news_url=None",
        "--LabApp.check_for_updates_class=jupyterlab.handlers.announcements.NeverCheckForUpdate",
        "--LabApp.extension_manager=readonly",  # no PyPI queries for the extension manager
        "--ServerApp.terminals_enabled=False",
        "--ServerApp.allow_root=True",  # CI runs as root
        "--ServerApp.shutdown_no_activity_timeout=600",  # a server left behind by a killed test exits by itself
        "--MappingKernelManager.cull_idle_timeout=600",  # ... and so do its idle kernels
    ]
    log_path = tmp_dir / "jupyterlab.log"
    with open(log_path, "wb") as log:
        process = subprocess.Popen(
            command, cwd=root_dir, env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
    lab = JupyterLab(process, port, token, root_dir, log_path)
    try:
        _wait_until_answers(lab, time.monotonic() + STARTUP_TIMEOUT)
        yield lab
    finally:
        left = _stop(lab)
        if left:
            raise RuntimeError(f"processes of the JupyterLab server still alive after shutdown: {left}")
        if port_in_use(port):
            raise RuntimeError(f"port {port} still answers after JupyterLab was stopped")

