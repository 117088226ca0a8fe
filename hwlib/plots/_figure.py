"""What every figure module shares: a figure that needs no display, and PNG bytes of it."""

from __future__ import annotations

import io

from matplotlib.figure import Figure


def new_figure(width=6.4, height=4.0, dpi=100):
    """A figure that needs no display and no pyplot state."""
    return Figure(figsize=(width, height), dpi=dpi, layout="constrained")


def figure_png(figure):
    """The figure rendered to PNG bytes."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()
