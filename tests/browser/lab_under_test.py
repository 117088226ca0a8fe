"""A throwaway JupyterLab server for the browser tests, the Chromium they drive it with, and the
helpers that drive a notebook in it like a student (open, Run All, read errors, add a cell).

(Named so as not to shadow the ``jupyter_server`` and ``jupyterlab_server`` packages.)

``running_jupyterlab(root_dir, tmp_dir)`` starts JupyterLab from the test's own Python
environment (``sys.executable -m jupyter lab``; with ``app="notebook"``, Notebook 7, and with
``prefix``, under a base URL as on a JupyterHub) on a free port of 127.0.0.1 with a random token,
with its config, runtime, settings and workspace folders inside ``tmp_dir`` so nothing leaks
between runs, waits until it answers, and on the way out, however the ``with`` block ends,
shuts down its kernels, stops the server (SIGTERM, then SIGKILL after a timeout), kills any of
its processes that are left (kernels included) and checks that the port is free again.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
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
    app: str = "lab"
    prefix: str = "/"

    @property
    def base_url(self):
        return f"http://127.0.0.1:{self.port}{self.prefix.rstrip('/')}"

    def url(self, path):
        """The browser URL of notebook ``path`` (relative to the root dir): in a fresh JupyterLab
        workspace, or Notebook 7's page for it."""
        if self.app == "notebook":
            return f"{self.base_url}/notebooks/{Path(path).as_posix()}?token={self.token}"
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
def running_jupyterlab(root_dir, tmp_dir, app="lab", prefix="/"):
    """Start JupyterLab (or ``app``) serving ``root_dir`` under ``prefix``; yield a ``JupyterLab``; always stop it."""
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
        sys.executable, "-m", "jupyter", app,
        "--no-browser",
        f"--ServerApp.base_url={prefix}",
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
    lab = JupyterLab(process, port, token, root_dir, log_path, app, prefix)
    try:
        _wait_until_answers(lab, time.monotonic() + STARTUP_TIMEOUT)
        yield lab
    finally:
        left = _stop(lab)
        if left:
            raise RuntimeError(f"processes of the JupyterLab server still alive after shutdown: {left}")
        if port_in_use(port):
            raise RuntimeError(f"port {port} still answers after JupyterLab was stopped")



# --- driving a notebook in JupyterLab like a student (Playwright pages) -------------------------------
#
# Shared by the browser tests: open a notebook, Run All, find the outputs a student reads as errors,
# add and run a cell. Every wait is bounded, and a Run All ends as soon as a cell fails.

OPEN_TIMEOUT_MS = 60_000  # JupyterLab loaded, notebook shown, kernel idle
RUN_TIMEOUT_S = 480  # all cells of one notebook run (p1 takes ~25 s on a quiet 2-core machine, minutes when 8 jobs share it)
CELL_TIMEOUT_S = 300  # one cell running this long with no other cell finishing: the run has hung
CLEAR_TIMEOUT_MS = 30_000
STOPPED_S = 3  # no cell queued or running for this long: the Run All has ended

# How JupyterLab 4 shows an exception: not as an "application/vnd.jupyter.error" output (it never
# renders that mime type) but as a stderr output holding the traceback, or the short message of an
# exception with _render_traceback_ ("TODO 1.1.1 is not done yet: ..."). A warning or a print to
# stderr is not an error.
ERROR_TEXT = r"Traceback \(most recent call last\)|^\s*[A-Za-z_][\w.]*(Error|Exception|Interrupt|Exit)\b.*:|is not done yet"
ERROR_OUTPUTS_JS = r"""(root) => {
    const errorText = new RegExp(%r, 'm');
    const cells = [...(root || document).querySelectorAll('.jp-NotebookPanel:not(.lm-mod-hidden) .jp-Notebook .jp-Cell')];
    const found = [];
    cells.forEach((cell, index) => {
        for (const output of cell.querySelectorAll('.jp-OutputArea-output')) {
            const mime = output.dataset.mimeType;
            if (mime === 'application/vnd.jupyter.error'
                || (mime === 'application/vnd.jupyter.stderr' && errorText.test(output.textContent))) {
                found.push({cell: index, text: output.textContent});
            }
        }
    });
    return found;
}""" % ERROR_TEXT

CELL_STATE_JS = """() => {
    const panel = document.querySelector('.jp-NotebookPanel:not(.lm-mod-hidden)');
    const prompts = panel ? [...panel.querySelectorAll('.jp-CodeCell .jp-InputPrompt')].map(element => element.textContent.trim()) : [];
    const errors = (%s)(panel).length;
    return {prompts, errors};
}""" % ERROR_OUTPUTS_JS


def watch_kernel_errors(page):
    """Collect the exceptions the kernel reports on the page's websockets (iopub "error" messages), as
    a list of {"ename", "evalue"} that fills as they arrive: what JupyterLab renders as error outputs."""
    found = []

    def on_frame(payload):
        message = parse_kernel_frame(payload)
        if message and message.get("channel") == "iopub" and message["header"].get("msg_type") == "error":
            found.append({key: message["content"].get(key) for key in ("ename", "evalue")})

    page.on("websocket", lambda socket: socket.on("framereceived", on_frame))
    return found


def parse_kernel_frame(payload):
    """One websocket frame of JupyterLab's kernel protocol (v1.kernel.websocket.jupyter.org: uint64
    offsets, then channel, header, parent header, metadata, content) or of the JSON protocol; None
    for any other frame."""
    try:
        if isinstance(payload, (bytes, bytearray)):
            count = int.from_bytes(payload[:8], "little")
            offsets = [int.from_bytes(payload[8 * (index + 1):8 * (index + 2)], "little") for index in range(count)]
            parts = [payload[start:end] for start, end in zip(offsets, offsets[1:])]
            channel, header, _parent, _metadata, content = (part.decode() for part in parts[:5])
            return {"channel": channel, "header": json.loads(header), "content": json.loads(content)}
        message = json.loads(payload)
        if isinstance(message, dict) and "header" in message and "channel" in message:
            return message
    except (ValueError, UnicodeDecodeError, IndexError):
        pass
    return None


def new_page(browser, default_timeout_ms=30_000):
    """A new tab that keeps the browser console's errors (``page.console_errors``) and the kernel's
    exceptions (``page.kernel_errors``)."""
    page = browser.new_page()
    page.set_default_timeout(default_timeout_ms)
    console_errors = []
    page.on("console", lambda message: console_errors.append(message.text) if message.type == "error" else None)
    page.console_errors = console_errors
    page.kernel_errors = watch_kernel_errors(page)
    return page


def console_summary(page):
    errors = getattr(page, "console_errors", [])
    return "\nbrowser console errors:\n" + "\n".join(errors[-20:]) if errors else ""


def wait_for_idle_kernel(page, timeout_ms):
    """The status bar's kernel item reads "Python 3 (ipykernel) | Idle"."""
    page.locator("#jp-main-statusbar .jp-StatusBar-TextItem", has_text=re.compile(r"\| Idle$")).first.wait_for(timeout=timeout_ms)


def open_notebook(page, lab, path):
    """Open ``path`` (relative to the server's root) in a fresh workspace and wait for an idle kernel."""
    page.goto(lab.url(path), timeout=OPEN_TIMEOUT_MS)
    page.locator(".jp-NotebookPanel .jp-Notebook .jp-Cell").first.wait_for(timeout=OPEN_TIMEOUT_MS)
    wait_for_idle_kernel(page, OPEN_TIMEOUT_MS)


def menu(page, menu_name, item_label):
    page.locator(".lm-MenuBar-item", has_text=re.compile(rf"^{re.escape(menu_name)}$")).click()
    page.locator(".lm-Menu-item:visible .lm-Menu-itemLabel", has_text=re.compile(rf"^{re.escape(item_label)}$")).click()


def error_outputs(page):
    """The outputs a student reads as errors, as [{"cell": index, "text": ...}], in cell order."""
    return page.evaluate(ERROR_OUTPUTS_JS)


def run_all_cells(page, timeout_s=RUN_TIMEOUT_S, cell_timeout_s=CELL_TIMEOUT_S):
    """Clear every output, then Run > Run All Cells, and wait until every code cell has run or a cell
    failed (JupyterLab stops a Run All there: no cell is queued any more). Returns {"prompts", "errors"}
    (errors: the count of error outputs). Fails if no cell finished for ``cell_timeout_s`` or the run
    took ``timeout_s``."""
    menu(page, "Edit", "Clear Outputs of All Cells")
    page.wait_for_function(
        "() => document.querySelectorAll('.jp-NotebookPanel:not(.lm-mod-hidden) .jp-OutputArea-output').length === 0",
        timeout=CLEAR_TIMEOUT_MS,
    )
    menu(page, "Run", "Run All Cells")
    started = last_change = time.monotonic()
    last_prompts, stopped_since = None, None
    while True:
        state = page.evaluate(CELL_STATE_JS)
        pending = any(prompt == "[*]:" for prompt in state["prompts"])
        all_ran = bool(state["prompts"]) and all(re.fullmatch(r"\[\d+\]:", prompt) for prompt in state["prompts"])
        if not pending and (all_ran or state["errors"] > 0):
            break
        now = time.monotonic()
        # A Run All queues every cell ([*]) at once: none queued any more means the run has stopped,
        # at an error even if no output shows one (the caller sees the cells that did not run).
        stopped_since = (stopped_since or now) if not pending and state["prompts"] else None
        if stopped_since is not None and now - stopped_since > STOPPED_S:
            break
        if state["prompts"] != last_prompts:
            last_prompts, last_change = state["prompts"], now
        running = [index for index, prompt in enumerate(state["prompts"]) if prompt == "[*]:"][:1]
        if now - last_change > cell_timeout_s:
            raise TimeoutError(f"Run All: no code cell finished for {cell_timeout_s} s (running: code cell {running}); "
                               f"prompts {state['prompts']}" + console_summary(page))
        if now - started > timeout_s:
            raise TimeoutError(f"Run All took more than {timeout_s} s (running: code cell {running})" + console_summary(page))
        time.sleep(0.25)
    wait_for_idle_kernel(page, cell_timeout_s * 1000)
    return page.evaluate(CELL_STATE_JS)


def run_in_new_cell(page, code, timeout_ms=60_000):
    """Add a code cell at the end of the open notebook, type ``code`` into it and run it; return the
    texts of its outputs once the kernel is idle again."""
    cells = page.locator(".jp-NotebookPanel:not(.lm-mod-hidden) .jp-Notebook .jp-Cell")
    count = cells.count()
    cells.last.locator(".jp-InputPrompt").click()  # select the last cell (command mode)
    page.keyboard.press("Escape")
    page.keyboard.press("b")  # insert a cell below
    page.wait_for_function(f"() => document.querySelectorAll('.jp-NotebookPanel:not(.lm-mod-hidden) .jp-Notebook .jp-Cell').length > {count}")
    cell = cells.nth(count)
    cell.locator(".cm-content").click()
    page.keyboard.insert_text(code)
    page.keyboard.press("Shift+Enter")
    prompt = cell.locator(".jp-InputPrompt")
    page.wait_for_function("element => /^\\[\\d+\\]:$/.test(element.textContent.trim())", arg=prompt.element_handle(), timeout=timeout_ms)
    wait_for_idle_kernel(page, timeout_ms)
    return cell.locator(".jp-OutputArea-output").all_inner_texts()
