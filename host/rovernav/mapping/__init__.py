"""Occupancy from the sonar: a log-odds grid fed by every reading (see sonar_map), and what the
host has learned of the arena from it, folded into the planner's grid, saved and reloaded
(see learned_map)."""

from .learned_map import Echo, LearnedMap
from .sonar_map import SensorModel, SonarMap, SonarReading, echo_point, sonar_origin

__all__ = ["Echo", "LearnedMap", "SensorModel", "SonarMap", "SonarReading", "echo_point", "sonar_origin"]
