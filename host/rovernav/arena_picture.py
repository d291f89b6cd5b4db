"""The arena from above, in a picture: its border, boxes, walls and posts (known ones grey,
unknown ones hatched), what the host's map holds, the sonar's echoes, the start and the target.

Drawn under the simulator's summary picture (evaluation/report.py) and the replay's (runlog/replay.py):
it needs a scenario and a mission (anything with .scenario and .mission), not the simulator.
"""

from __future__ import annotations

import cv2
import numpy as np


class Canvas:
    """Arena metres to picture pixels (y up in the arena, down in the picture)."""

    def __init__(self, width_m: float, height_m: float, px_per_m: float = 400, margin_px: int = 20):
        self.s, self.m = px_per_m, margin_px
        self.h_m = height_m
        self.img = np.full(
            (int(height_m * px_per_m) + 2 * margin_px, int(width_m * px_per_m) + 2 * margin_px, 3), 245, np.uint8
        )

    def pt(self, x_m: float, y_m: float) -> tuple[int, int]:
        return int(round(self.m + x_m * self.s)), int(round(self.m + (self.h_m - y_m) * self.s))

    def pts(self, xy) -> np.ndarray:
        return np.array([self.pt(x, y) for x, y in xy], np.int32)


def _fill(img: np.ndarray, draw, known: bool) -> None:
    """Paint a shape as the boxes are: known solid grey, unknown light red with a hatch.
    `draw(mask, colour)` draws the filled shape into a single-channel mask."""
    mask = np.zeros(img.shape[:2], np.uint8)
    draw(mask, 255)
    ys, xs = np.nonzero(mask)
    if not len(xs):
        return
    inside = mask > 0
    if known:
        img[inside] = (110, 110, 110)
        return
    img[inside] = (150, 150, 200)
    x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
    hatch = np.zeros_like(mask)
    for k in range(x0 - (y1 - y0), x1 + 1, 8):  # the boxes' hatch: lines at 45°, 8 px apart
        cv2.line(hatch, (k, y1), (k + (y1 - y0), y0), 255, 1)
    img[inside & (hatch > 0)] = (90, 90, 160)


def draw_arena(canvas: Canvas, sim, grid=None) -> None:
    sc = sim.scenario
    img = canvas.img
    if grid is not None:  # what the host's map holds: inflated cells shaded, sonar cells dark
        res = grid.resolution_m
        inflated = grid.inflated
        for iy, ix in zip(*np.nonzero(inflated)):  # layers are (rows = y, columns = x)
            x0, y0 = canvas.pt(ix * res, (iy + 1) * res)
            x1, y1 = canvas.pt((ix + 1) * res, iy * res)
            cv2.rectangle(img, (x0, y0), (x1, y1), (225, 225, 235), -1)
    cv2.rectangle(img, canvas.pt(0, sc.arena.height_m), canvas.pt(sc.arena.width_m, 0), (60, 60, 60), 2)
    for o in sc.obstacles:
        p0, p1 = canvas.pt(o.x_m - o.w_m / 2, o.y_m + o.h_m / 2), canvas.pt(o.x_m + o.w_m / 2, o.y_m - o.h_m / 2)
        if o.known:
            cv2.rectangle(img, p0, p1, (110, 110, 110), -1)
        else:
            cv2.rectangle(img, p0, p1, (150, 150, 200), -1)
            for k in range(p0[0] - (p1[1] - p0[1]), p1[0], 8):  # hatch: unknown to the planner
                cv2.line(
                    img,
                    (max(k, p0[0]), p0[1] + max(0, p0[0] - k)),
                    (min(k + (p1[1] - p0[1]), p1[0]), p1[1] - max(0, k + (p1[1] - p0[1]) - p1[0])),
                    (90, 90, 160),
                    1,
                )
    for w in getattr(sc, "walls", ()):
        _fill(img, lambda m, c: cv2.fillPoly(m, [canvas.pts(w.corners())], c, cv2.LINE_AA), w.known)
    for o in getattr(sc, "posts", ()):
        centre, r = canvas.pt(o.x_m, o.y_m), max(1, int(round(o.radius_m * canvas.s)))
        _fill(img, lambda m, c: cv2.circle(m, centre, r, c, -1, cv2.LINE_AA), o.known)
    for e in sim.mission.echoes:
        cv2.circle(img, canvas.pt(*e.point(sim.mission.grid.config.sonar_offset_m)), 3, (0, 0, 200), -1)
    cv2.circle(img, canvas.pt(sc.start.x_m, sc.start.y_m), 7, (0, 150, 0), 2)
    cv2.drawMarker(img, canvas.pt(sc.target.x_m, sc.target.y_m), (0, 170, 230), cv2.MARKER_STAR, 18, 2)
