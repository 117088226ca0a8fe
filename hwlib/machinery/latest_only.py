"""Redraw only the latest: the slider panel's and the landscape explorer's redraws.

A widget callback may come from several threads at once (the kernel's and a thread of the
notebook's own), and a redraw takes a moment. ``LatestOnly`` runs the redraws one at a time and
always once more after the last request, so a burst of changes ends on the latest state and no
picture of an older one is shown after it.
"""

from __future__ import annotations

import contextlib
import threading


class LatestOnly:
    """Runs ``draw()`` one call at a time, and always once more after the last ``request()``.

    ``request()`` from any thread: if nobody is drawing, the calling thread draws, and keeps
    drawing until no request arrived during its last draw; if somebody is drawing, the request
    is only noted and the call returns at once. ``pending`` says, during a draw, whether a newer
    request is waiting (its picture then follows at once). Inside ``with held():`` requests are
    only noted; leaving the block makes one request for all of them.
    """

    def __init__(self, draw):
        self._draw = draw
        self._lock = threading.Lock()
        self._pending = False
        self._drawing = False
        self._holds = 0

    @property
    def pending(self):
        with self._lock:
            return self._pending

    def request(self):
        with self._lock:
            self._pending = True
            if self._drawing or self._holds:
                return
            self._drawing = True
        try:
            while True:
                with self._lock:
                    if not self._pending or self._holds:
                        self._drawing = False
                        return
                    self._pending = False
                self._draw()
        except BaseException:
            with self._lock:
                self._drawing = False
            raise

    @contextlib.contextmanager
    def held(self):
        with self._lock:
            self._holds += 1
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
            self.request()
