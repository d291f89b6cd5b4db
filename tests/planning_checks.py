"""A test helper for the planning tests: the shared scenarios' grids, and a check of a path's
cells by fine sampling. Used by test_planning_astar.py, test_planning_grid.py and
test_planning_paths.py."""

from __future__ import annotations

import numpy as np

from rovernav.planning import OccupancyGrid, PlannerConfig
from rovernav.scenario import load_scenario


def sampled_cells_free(blocked: np.ndarray, res: float, waypoints) -> bool:
    """Walk each segment in steps of a twentieth of a cell: does every sample fall in a free cell?"""
    ny, nx = blocked.shape
    pts = np.asarray(waypoints, dtype=float)
    for a, b in zip(pts[:-1], pts[1:]):
        n = int(np.hypot(*(b - a)) / (res / 20)) + 2
        t = np.linspace(0.0, 1.0, n)[:, None]
        p = a + t * (b - a)
        ix = np.minimum(np.floor(p[:, 0] / res).astype(int), nx - 1)
        iy = np.minimum(np.floor(p[:, 1] / res).astype(int), ny - 1)
        if blocked[iy, ix].any():
            return False
    return True


SEED_SCENARIOS = ("seed-large-obstacles", "seed-small-obstacles", "out-and-back", "seed-fig4-8-unknown-obstacle")


def scenario_grid(name: str, config: PlannerConfig | None = None):
    scenario = load_scenario(name)
    return scenario, OccupancyGrid.from_scenario(scenario, config, all_obstacles=True)
