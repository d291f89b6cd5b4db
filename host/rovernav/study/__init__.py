"""The seed study (Russo 2024, Mars rover): moving to a pose, A* on a crater map, EKF localisation.

    run = simulate_pose()                         # P0 → P1 with the report's gains, Curiosity's 4 cm/s
    cmap = crater_map(seed=0); path = plan_on_map(cmap)   # P1 → P2 on a generated crater map
    loc = run_localisation(); check = nees_monte_carlo(20)

Lengths in metres, angles in radians from the x axis (counter-clockwise), times in seconds.
"""

from .crater import REPORT_P2, CraterMap, crater_map, path_is_clear, plan_on_map, plot_crater_plan
from .ekf import LocalisationRun, LocalisationScenario, NeesCheck, nees_monte_carlo, plot_localisation, run_localisation
from .pose import (
    CURIOSITY_VMAX_M_S,
    REPORT_P0,
    REPORT_P1,
    PoseGains,
    PoseRun,
    from_polar,
    plot_pose,
    simulate_pose,
    to_polar,
)

__all__ = [
    "CURIOSITY_VMAX_M_S",
    "REPORT_P0",
    "REPORT_P1",
    "REPORT_P2",
    "CraterMap",
    "LocalisationRun",
    "LocalisationScenario",
    "NeesCheck",
    "PoseGains",
    "PoseRun",
    "crater_map",
    "from_polar",
    "nees_monte_carlo",
    "path_is_clear",
    "plan_on_map",
    "plot_crater_plan",
    "plot_localisation",
    "plot_pose",
    "run_localisation",
    "simulate_pose",
    "to_polar",
]
