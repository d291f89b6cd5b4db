"""Occupancy from the sonar: a log-odds grid fed by every reading (see sonar_map)."""
from .sonar_map import SensorModel, SonarMap, SonarReading, echo_point, sonar_origin

__all__ = ["SensorModel", "SonarMap", "SonarReading", "echo_point", "sonar_origin"]
