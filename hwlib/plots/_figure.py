"""What every figure module shares: a figure that needs no display, PNG bytes of it, and where to
put the labels of a line's points."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.figure import Figure

LABEL_FONT_SIZE = 8  # points: the labels of a line's points (the sweep's shares, the training path's iterations)
LABEL_DISTANCE = 6  # points from a point to the edge of its label's box, about
CLEAR_ANGLE = 60  # degrees: a side this far from the line's segments is as good as any farther one


def new_figure(width=6.4, height=4.0, dpi=100):
    """A figure that needs no display and no pyplot state."""
    return Figure(figsize=(width, height), dpi=dpi, layout="constrained")


def figure_png(figure):
    """The figure rendered to PNG bytes."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()


def label_offsets(ax, xs, ys, texts, fontsize=LABEL_FONT_SIZE, distance=LABEL_DISTANCE):
    """For each point of the line through (``xs``, ``ys``) (data coordinates, in order), the offset in
    points of the centre of its label ``texts[i]``: of eight sides, the one farthest in angle from the
    line's segments at that point, among those where the label stays inside the axes and clear of
    the labels placed before it (above the point first). Call it once the figure is laid out."""
    points = ax.transData.transform(np.column_stack([xs, ys]))
    scale = ax.figure.dpi / 72  # pixels per point
    sides = [90, 270, 45, 135, 315, 225, 0, 180]  # degrees: up first, then down, then the diagonals, then across
    inside, placed, offsets = ax.bbox, [], []
    for index, ((x, y), text) in enumerate(zip(points, texts)):
        width, height = (0.62 * fontsize * len(text) + 4) * scale, (fontsize + 3) * scale
        segments = [np.degrees(np.arctan2(py - y, px - x)) for px, py in points[max(index - 1, 0):index + 2]
                    if np.hypot(px - x, py - y) > 1]
        best, best_score, best_box = (0.0, 0.0), -np.inf, None
        for side in sides:
            ux, uy = np.cos(np.radians(side)), np.sin(np.radians(side))
            dx = ux * (distance * scale + width / 2)  # the box's near edge about ``distance`` from the point
            dy = uy * (distance * scale + height / 2)
            box = (x + dx - width / 2, y + dy - height / 2, x + dx + width / 2, y + dy + height / 2)
            score = min([abs((side - angle + 180) % 360 - 180) for angle in segments] + [CLEAR_ANGLE])
            if box[0] < inside.x0 or box[2] > inside.x1 or box[1] < inside.y0 or box[3] > inside.y1:
                score -= 360
            if any(box[0] < other[2] and other[0] < box[2] and box[1] < other[3] and other[1] < box[3] for other in placed):
                score -= 180
            if score > best_score + 1e-9:
                best, best_score, best_box = (dx / scale, dy / scale), score, box
        placed.append(best_box)
        offsets.append(best)
    return offsets
