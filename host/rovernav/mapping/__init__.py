"""Occupancy from the sonar: a log-odds grid fed by every reading (see sonar_map)."""
from .sonar_map import SensorModel, SonarMap, SonarReading

__all__ = ["SensorModel", "SonarMap", "SonarReading"]
