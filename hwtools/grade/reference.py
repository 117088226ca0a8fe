"""The reference server: sandboxed processes that run the reference kit alone and answer for it.

No process that runs a student's code holds reference code. What needs the reference runs here:
the calls a student's worker makes to other TODOs' functions (relayed by ``broker.py``), every
CartPole episode the 1.3.x checks count, the reference's own answers on every case (visible and
hidden: this process runs no student code, so hidden inputs may reach it) and the services that
re-score a run (the notebook's training run of 1.3.3).

A ``ReferencePool`` keeps a few servers for one ``Grader``: each is a worker process
(``Sandbox.start``) on one private copy of the reference kit, told by its first message to serve
(``in_sandbox/runtime.py``). A run borrows one for its whole conversation (``acquire``/``release``); a server
that failed or timed out is ended, never lent again. Idle servers end after ``idle`` seconds, and
all of them with ``close()``. The kit is written in a folder only this user can read. A pool is
``trusted`` when its kit holds no student code (the reference's; the student edition's preview
serves the student's own kit, untrusted): under the user fallback a trusted server runs as the
grader's own user (``Sandbox.run_kind``), so no server shares a uid with a student's run and the
pool's users are left to students' runs.

Interface (for the grader and the broker)::

    pool = ReferencePool(sandbox, files, trusted=True)  # files: {relative path: text} of the kit
    server = pool.acquire(need=seconds)               # a live server with that much life left
    number = server.send({"op": "call", ...})         # numbered by the server object
    reply = server.receive(deadline)                  # a dict, or raises ServerFailed / ServerTimeout
    pool.release(server, broken=False)
    result = pool.probe(probe, args, time_limit)      # {"status", "error", "values"}: a probe on the reference
    pool.close()
"""

from __future__ import annotations

import queue
import tempfile
import threading
import time
from pathlib import Path

from hwtools.grade import kits
from hwtools.grade.in_sandbox.channel import ChannelTimeout

LIFETIME = 3600.0  # seconds a server lives at most (its wall-clock and CPU limit)
SETUP_SECONDS = 120.0  # to start and import the kit
IDLE_SECONDS = 10.0  # an unused server ends after this long
KEEP = 4  # idle servers kept at most
CLOSE_SECONDS = 60.0  # for a closed server's processes to be gone


class ServerFailed(Exception):
    """The server stopped, or answered something it should not: it is ended."""


class ServerTimeout(ServerFailed):
    """No answer before the deadline of the run that asked."""


class _Spawner:
    """One long-lived thread that starts every server process (and every grading's zygote, which
    serves later gradings too: ``spawn``). bubblewrap's --die-with-parent ends a sandbox when the
    *thread* that started it ends, and runs borrow servers from short-lived threads (a
    ThreadPoolExecutor's): so none of those may start one."""

    def __init__(self):
        self._jobs = queue.SimpleQueue()
        threading.Thread(target=self._serve, name="hwgrade-reference-spawner", daemon=True).start()

    def _serve(self):
        while True:
            job, done = self._jobs.get()
            try:
                done["value"] = job()
            except BaseException as error:  # noqa: BLE001 - handed to the thread that asked
                done["error"] = error
            done["event"].set()

    def run(self, job):
        done = {"event": threading.Event()}
        self._jobs.put((job, done))
        done["event"].wait()
        if "error" in done:
            raise done["error"]
        return done["value"]


_SPAWNER = []
_SPAWNER_LOCK = threading.Lock()


def spawn(job):
    """``job()`` (which starts a sandbox that outlives the thread asking for it) in the spawner's thread."""
    with _SPAWNER_LOCK:
        if not _SPAWNER:
            _SPAWNER.append(_Spawner())
    return _SPAWNER[0].run(job)


class ReferenceServer:
    """One server process: ``send`` numbers each message, ``receive`` checks nothing but the form."""

    def __init__(self, sandbox, kit_dir, lifetime=LIFETIME, trusted=True):
        # no grading's turn: a server answers the run that holds it (the preview's server, on the
        # student's own kit, holds no secret: no reference, no hidden input)
        self.process = spawn(lambda: sandbox.start(kit_dir, lifetime, trusted=trusted))
        self.sent, self.broken, self.closed, self.last_used = 0, False, False, time.monotonic()
        try:
            number = self.send({"op": "setup", "mode": "server"})
            reply = self.receive(time.monotonic() + SETUP_SECONDS)
            if reply.get("op") != "ready" or reply.get("re") != number:
                raise ServerFailed("the reference server did not start")
        except ServerFailed:
            self.close()
            raise

    @property
    def remaining(self):
        return self.process.deadline - time.monotonic()

    def send(self, message, deadline=None):
        """Number and write ``message`` by ``deadline`` (default: the server's lifetime)."""
        self.sent += 1
        try:
            self.process.send(dict(message, n=self.sent), deadline)
        except OSError:
            self.broken = True
            raise ServerFailed("the reference server stopped reading") from None
        except ChannelTimeout:
            self.broken = True
            if deadline is not None and time.monotonic() < self.process.deadline:
                raise ServerTimeout("no room to write in time") from None
            raise ServerFailed("the reference server stopped reading") from None
        return self.sent

    def receive(self, deadline):
        reply = self.process.receive(deadline)
        if isinstance(reply, str):
            self.broken = True
            status = reply.split(":", 1)[0]
            if status == "timeout" and time.monotonic() < self.process.deadline:
                raise ServerTimeout("no answer in time")
            raise ServerFailed(f"the reference server stopped ({status})")
        return reply

    def request(self, message, deadline):
        """Send ``message`` and return the ``done`` that answers it (for probes: no call-backs)."""
        number = self.send(message, deadline)
        reply = self.receive(deadline)
        if reply.get("op") != "done" or reply.get("re") != number:
            self.broken = True
            raise ServerFailed("the reference server answered out of turn")
        return reply

    def close(self):
        if self.closed:
            return None
        self.broken = self.closed = True
        try:
            self.process.send({"op": "exit", "n": self.sent + 1}, time.monotonic() + 1.0)
        except (OSError, ChannelTimeout):
            pass
        return self.process.finish(graceful=False)


class ReferencePool:
    """Reference servers for one grader, on one copy of the kit ``files`` (see the module docstring)."""

    def __init__(self, sandbox, files, idle=IDLE_SECONDS, lifetime=LIFETIME, trusted=True):
        self.sandbox, self.idle, self.lifetime, self.trusted = sandbox, float(idle), float(lifetime), trusted
        self.files = dict(files) | kits.sandboxed_files()
        self.digest = kits.files_digest(self.files)
        self._folder, self._idle, self._lock, self._timer, self._closed = None, [], threading.Lock(), None, False
        self._made = []  # the servers started and not known to have ended

    def _kit(self):
        if self._folder is None:
            self._folder = Path(tempfile.mkdtemp(prefix="hwgrade-reference-"))  # mode 0700
            kits.write_files(self.files, self._folder / "kit")
        return self._folder / "kit"

    def acquire(self, need=0.0):
        """A server with at least ``need`` seconds to live, started if none is idle."""
        with self._lock:
            if self._closed:
                raise ServerFailed("the reference servers were closed")
            while self._idle:
                server = self._idle.pop()
                if not server.broken and server.remaining > need + 60:
                    return server
                threading.Thread(target=server.close, daemon=True).start()
            kit = self._kit()
        server = ReferenceServer(self.sandbox, kit, max(self.lifetime, need + SETUP_SECONDS + 60), self.trusted)
        with self._lock:
            self._made = [made for made in self._made if not made.process.ended.is_set()] + [server]
        return server

    def release(self, server, broken=False):
        if server is None:
            return
        if broken or server.broken or self._closed:
            server.close()
            return
        server.last_used = time.monotonic()
        with self._lock:
            self._idle.append(server)
            extra = self._idle[:-KEEP]
            del self._idle[:-KEEP]
            if self._timer is None:
                self._timer = threading.Timer(self.idle, self._reap)
                self._timer.daemon = True
                self._timer.start()
        for old in extra:
            old.close()

    def _reap(self):
        now = time.monotonic()
        with self._lock:
            self._timer = None
            stale = [server for server in self._idle if now - server.last_used >= self.idle]
            self._idle = [server for server in self._idle if server not in stale]
            if self._idle:
                self._timer = threading.Timer(self.idle, self._reap)
                self._timer.daemon = True
                self._timer.start()
        for server in stale:
            server.close()

    def probe(self, probe, args, time_limit):
        """Run ``probe`` on ``args`` in a reference server: {"status", "error", "values"}."""
        server = self.acquire(need=time_limit)
        broken = True
        try:
            reply = server.request({"op": "probe", "probe": probe, "args": args}, time.monotonic() + time_limit)
            broken = False
        finally:
            self.release(server, broken)
        values = reply.get("values") if isinstance(reply.get("values"), dict) else {}
        return {"status": "ok" if reply.get("status") == "ok" else "error", "error": str(reply.get("error", "")),
                "warnings": [], "values": values}

    def close(self):
        with self._lock:
            self._closed = True
            idle, self._idle = self._idle, []
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
        for server in idle:
            server.close()
        for server in self._made:  # those closing elsewhere too: every process of this pool is gone on return
            server.close()
            server.process.ended.wait(CLOSE_SECONDS)
        if self._folder is not None:
            kits.remove_tree(self._folder)
            self._folder = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001 - at interpreter exit anything may be gone
            pass
