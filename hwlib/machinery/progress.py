"""A progress bar with a time estimate, for the kit's long cells.

In a notebook (an IPython kernel) ``Progress`` shows an ipywidgets bar and a line such as
"reward landscape: 3,000 of 8,405 episodes · 6 s so far · about 11 s left"; elsewhere (pytest,
a script, the grader) it shows nothing. ipywidgets is a base dependency of the kit and the bar
must be one of its widgets anyway (tqdm's notebook bar is built on it too), so no new package.

nbval compares a cell's text outputs with the stored ones. The bar is displayed once, with the
first news of the work (a TODO not done yet that stops the work before it starts shows no bar,
only its two lines), and its plain-text form (``repr``) is fixed by its title and size, never by the
time or the progress: the bar changes only through the widget's state, which nbval does not
compare. A cell that shows a bar therefore gives the same text output on every run.
"""

from __future__ import annotations

import time

_MIN_INTERVAL = 0.2  # seconds between two redraws of the bar


def in_notebook():
    """Whether this process is an IPython kernel that can show widgets."""
    try:
        from IPython import get_ipython  # noqa: PLC0415 - only where IPython is installed
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


class Progress:
    """``with Progress("reward landscape", 8405, "episodes") as bar: ... bar.advance(1) ...``

    ``unit`` None leaves the counts out of the line (``detail`` says how far it is). ``title`` None
    shows nothing (the work is done all the same). ``show`` forces the widget on
    (True) or off (False); by default it is shown in a notebook only. ``widget`` is the ipywidgets
    box (None when not shown).
    """

    def __init__(self, title, total, unit="", show=None):
        self.title, self.total, self.unit = title, max(int(total), 1), unit
        self.done = 0
        self.detail = ""
        self.note = ""  # said after "done in ..." (e.g. that a stored result was used)
        self.started = self._drawn = None
        self.status = "running"
        self.widget = None
        self._shown = False
        if title is not None and (in_notebook() if show is None else show):
            self.widget = _make_widget(self)

    def __enter__(self):
        self.started = time.perf_counter()
        return self

    def __exit__(self, kind, error, traceback):
        if kind is None:
            self.status, self.done = "done", self.total
        elif issubclass(kind, KeyboardInterrupt):
            self.status = "stopped by Kernel → Interrupt"
        elif getattr(error, "todo", None) is not None and not self._shown:
            return False  # a TODO not done yet, before any work: its two lines say it all, no bar above them
        else:
            self.status = "stopped: " + (str(error).splitlines() or [kind.__name__])[0]
        self._draw(force=True)
        return False

    def advance(self, count=1, detail=None):
        """``count`` more units are done (``detail``: a short note shown after the numbers)."""
        self.set(self.done + count, detail)

    def set(self, done, detail=None):
        self.done = min(max(int(done), 0), self.total)
        if detail is not None:
            self.detail = detail
        self._draw()

    @property
    def elapsed(self):
        return 0.0 if self.started is None else time.perf_counter() - self.started

    def seconds_left(self, elapsed=None):
        """The time estimate: the time so far scaled by the share still to do (None: too early to tell)."""
        elapsed = self.elapsed if elapsed is None else elapsed
        fraction = self.done / self.total
        if fraction <= 0.0 or elapsed < 1.0:
            return None
        return elapsed * (1.0 - fraction) / fraction

    def text(self):
        """The line beside the bar."""
        counted, elapsed = self.unit is not None, self.elapsed
        parts = [f"{self.title}: {self.done} of {self.total} {self.unit}".rstrip() if counted else self.title]
        if self.status == "done":
            return " · ".join([f"{self.title}: {self.total} {self.unit}".rstrip() if counted else self.title,
                               f"done in {format_seconds(elapsed)}", *([self.note] if self.note else [])])
        if self.detail:
            parts.append(self.detail)
        if self.status == "running":
            parts.append(f"{format_seconds(elapsed)} so far")
            left = self.seconds_left(elapsed)
            parts.append("estimating the time left…" if left is None else f"about {format_seconds(left)} left")
        else:
            parts.append(f"{self.status} after {format_seconds(elapsed)}")
        return " · ".join(parts)

    def _draw(self, force=False):
        now = time.perf_counter()
        if self.widget is None or (not force and self._drawn is not None and now - self._drawn < _MIN_INTERVAL):
            return
        self._drawn = now
        if not self._shown:  # shown with its first news, so a TODO not done yet shows no bar at all
            from IPython.display import display  # noqa: PLC0415

            display(self.widget)
            self._shown = True
        bar, label = self.widget.children
        bar.value = self.done / self.total
        bar.bar_style = {"running": "info", "done": "success"}.get(self.status, "danger")
        label.value = _escape(self.text())


def format_seconds(seconds):
    """'0.4 s', '12 s', '3 min 20 s', '2 h 05 min'."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, seconds = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {seconds:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


def _escape(text):
    import html  # noqa: PLC0415

    return html.escape(text)


def _make_widget(progress):
    import ipywidgets as widgets  # noqa: PLC0415

    class ProgressBox(widgets.HBox):
        def __repr__(self):  # the text nbval compares: fixed by the title and the size
            size = "" if progress.unit is None else f", {progress.total} {progress.unit}"
            return f"[progress bar: {progress.title}{size}]"

    bar = widgets.FloatProgress(value=0.0, min=0.0, max=1.0, layout=widgets.Layout(width="240px"))
    label = widgets.HTML(value=_escape(f"{progress.title}: starting…"))
    box = ProgressBox([bar, label])
    box.add_class("hwlib-progress")
    return box
