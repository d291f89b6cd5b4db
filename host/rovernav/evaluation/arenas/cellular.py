"""The cellular family: BARN's worlds (Perille et al., 2020), scaled to this rover."""

from __future__ import annotations

import heapq
import math

import cv2
import numpy as np

from .draw import _Box, _Draw, _Layout, _Redraw

# --- cellular: BARN's worlds, scaled to this rover -------------------------------------------------

#: BARN (Perille et al., 2020) draws its 300 worlds on a grid of 0.15 m cells for a Jackal
#: (0.51 x 0.43 m): random fill, then cellular-automaton smoothing, start and goal on the centre
#: line, and keeps only a world with a way through. Scaled by 0.56 so that its robot becomes
#: ours, a cell is 0.084 m.
CELLULAR_CELL_M = 0.084
CELLULAR_WIDTH_RANGE_M = (2.5, 4.0)
CELLULAR_HEIGHT_RANGE_M = (1.8, 3.0)
CELLULAR_FILL_RANGE = (0.10, 0.30)  # BARN's initial fill, the share of cells occupied
CELLULAR_SMOOTHING = (0, 4)  # BARN's smoothing iterations
CELLULAR_BOXES = (8, 120)  # boxes (merged cells) an arena may hold
CELLULAR_FIELDS = 6  # fields drawn with one fill and smoothing before one is carved


def _way_through(occ: np.ndarray, need_cells: float) -> bool:
    """Whether the middle of the field's left column and of its right column are joined through
    cells more than `need_cells` (centre to centre) from every occupied cell (outside the field
    is free floor)."""
    ny, nx = occ.shape
    free = np.pad((~occ).astype(np.uint8), 1, constant_values=1)
    room = cv2.distanceTransform(free, cv2.DIST_L2, 5)[1:-1, 1:-1] > need_cells
    _, labels = cv2.connectedComponents(room.astype(np.uint8), connectivity=4)
    a, b = (ny // 2, 0), (ny // 2, nx - 1)
    return bool(room[a] and room[b] and labels[a] == labels[b])


def _cheapest_way(cost: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """The cells (row, column) of the cheapest 4-connected way from start to goal (Dijkstra on
    weighted cells: planning.astar_cells searches a free/blocked grid, not costs)."""
    ny, nx = cost.shape
    best = np.full(cost.shape, np.inf)
    best[start] = 0.0
    came: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(0.0, start)]
    while heap:
        dist, here = heapq.heappop(heap)
        if here == goal:
            break
        if dist > best[here]:
            continue
        y, x = here
        for v, u in ((y + 1, x), (y - 1, x), (y, x + 1), (y, x - 1)):
            if 0 <= v < ny and 0 <= u < nx and dist + cost[v, u] < best[v, u]:
                best[v, u] = dist + cost[v, u]
                came[(v, u)] = here
                heapq.heappush(heap, (float(best[v, u]), (v, u)))
    way = [goal]
    while way[-1] != start:
        way.append(came[way[-1]])
    return way[::-1]


def _carve(occ: np.ndarray, need_cells: float, rng: np.random.Generator) -> int:
    """Frees a way from the middle of the field's left column to the middle of its right one,
    through one or two cells drawn at random between (so that it winds, as a way through a
    cave does): the cheapest way, where an occupied cell costs 40 and a free one 1, so that it
    follows the gaps there are, widened to a rover's width (the occupied cells within
    `need_cells`, rounded up, of it). Returns how many cells it freed."""
    ny, nx = occ.shape
    cost = 1.0 + 40.0 * occ
    k = int(rng.integers(1, 3))
    inner = [(int(rng.integers(ny // 5, ny - ny // 5)), int((i + 1) * nx / (k + 1))) for i in range(k)]
    points = [(ny // 2, 0), *inner, (ny // 2, nx - 1)]
    way = np.zeros(occ.shape, np.uint8)
    for a, b in zip(points, points[1:]):
        for cell in _cheapest_way(cost, a, b):
            way[cell] = 1
    freed = 0
    for r in (math.ceil(need_cells), math.ceil(need_cells) + 1):
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        wide = cv2.dilate(way, disk) > 0
        freed += int((occ & wide).sum())
        occ[wide] = False
        if _way_through(occ, need_cells):
            break
    return freed


def _smooth(occ: np.ndarray) -> np.ndarray:
    """One cellular-automaton step (BARN's, the cave rule): a cell with 5 or more occupied
    neighbours of its 8 becomes occupied, one with 3 or fewer becomes free, else it stays (outside
    the grid counts as free floor)."""
    padded = np.pad(occ.astype(np.int8), 1)
    n = sum(
        padded[1 + dy : padded.shape[0] - 1 + dy, 1 + dx : padded.shape[1] - 1 + dx]
        for dy in (-1, 0, 1)
        for dx in (-1, 0, 1)
        if (dx, dy) != (0, 0)
    )
    return np.where(n >= 5, True, np.where(n <= 3, False, occ))


def _cell_boxes(occ: np.ndarray, x0: float, y0: float, c: float) -> list[tuple[float, float, float, float]]:
    """The occupied cells as few boxes (x0, x1, y0, y1): each row's runs, merged with the same run
    of the rows above."""
    open_runs: dict[tuple[int, int], list[int]] = {}  # (first column, last column) -> [first row, last row]
    done = []
    for row in range(occ.shape[0]):
        runs, col = [], 0
        while col < occ.shape[1]:
            if occ[row, col]:
                end = col
                while end + 1 < occ.shape[1] and occ[row, end + 1]:
                    end += 1
                runs.append((col, end))
                col = end + 1
            else:
                col += 1
        for key in list(open_runs):
            if key not in runs:
                done.append((key, open_runs.pop(key)))
        for key in runs:
            open_runs.setdefault(key, [row, row])[1] = row
    done += list(open_runs.items())
    return [
        (round(x0 + a * c, 6), round(x0 + (b + 1) * c, 6), round(y0 + r0 * c, 6), round(y0 + (r1 + 1) * c, 6))
        for (a, b), (r0, r1) in done
    ]


def _cellular(d: _Draw) -> _Layout:
    c = CELLULAR_CELL_M
    W = d.width_m = d.u(*CELLULAR_WIDTH_RANGE_M, step_m=0.01)
    H = d.height_m = d.u(*CELLULAR_HEIGHT_RANGE_M, step_m=0.01)
    fill, smoothing = d.u(*CELLULAR_FILL_RANGE, step_m=0.01), d.whole(*CELLULAR_SMOOTHING)
    # The obstacle field between a start strip and a target strip, as BARN's lies between its
    # start and goal; both on the centre line.
    strip = d.margin_m + 0.1
    nx, ny = int((W - 2 * strip) / c), int(H / c)
    x0, y0 = (W - nx * c) / 2, (H - ny * c) / 2
    start, target = (round(d.margin_m, 3), round(H / 2, 3)), (round(W - d.margin_m, 3), round(H / 2, 3))
    # A way through for the rover: the cells its centre may stand on are those further than its
    # inflation from every occupied cell (centre to the occupied cell's edge), and the start's
    # side and the target's must be joined through them. BARN keeps only worlds with a way
    # through: a few fields are drawn with these numbers, and if none has one (a dense field for
    # a rover whose inflation spans 4 cells seldom does), a way is carved through the last along
    # a wandering line, so that the densities stay as drawn.
    need = d.inflation_m / c + 0.5
    for _attempt in range(CELLULAR_FIELDS):
        occ = d.rng.random((ny, nx)) < fill
        for _ in range(smoothing):
            occ = _smooth(occ)
        if _way_through(occ, need):
            carved = 0
            break
    else:
        carved = _carve(occ, need, d.rng)
        if not _way_through(occ, need):
            raise _Redraw("no way through after carving")
    boxes = [_Box(bx0, bx1, by0, by1, False, "cell") for bx0, bx1, by0, by1 in _cell_boxes(occ, x0, y0, c)]
    if not CELLULAR_BOXES[0] <= len(boxes) <= CELLULAR_BOXES[1]:
        raise _Redraw(f"{len(boxes)} boxes")
    return _Layout(
        W,
        H,
        start,
        d.heading(start, target),
        target,
        boxes,
        f"BARN-style cellular world: fill {fill:.2f}, {smoothing} smoothing steps, {len(boxes)} boxes "
        f"({int(occ.sum())} cells of {c * 100:.1f} cm), every one unknown"
        + (f"; {carved} cells carved for a way through" if carved else ""),
    )
