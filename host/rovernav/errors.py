"""The host's exceptions: one small tree, so a caller can catch exactly what it can handle.

    RovernavError
     ├── InputError (also a ValueError)   a file, flag or value the user gave cannot be used:
     │    ├── ConfigError                  rovernav.config
     │    ├── ScenarioError                rovernav.scenario
     │    └── MapFileError                 a learned-map file
     ├── LinkError                         the radio or the rover (rovernav.link.errors)
     ├── CameraError                       a camera that cannot be opened or stops delivering
     ├── NoPathError                       the planner found no path (rovernav.planning.errors)
     └── MissionFailed                     a mission that cannot go on (the reason in its message)
"""
from __future__ import annotations


class RovernavError(Exception):
    """Base of every error rovernav raises on purpose."""


class InputError(RovernavError, ValueError):
    """Something the user gave (a file, a flag, a value) cannot be used; the message names it."""


class MapFileError(InputError):
    """A learned-map file is missing, unreadable or not a valid map."""


class CameraError(RovernavError):
    """The camera could not be opened or stopped delivering frames."""


class MissionFailed(RovernavError):
    """The mission cannot go on: the rover refused it, faulted, stopped answering, or no path exists.
    `failure` is the kind (rovernav.mission.Failure), when the mission said it."""

    def __init__(self, message: str, failure=None):
        super().__init__(message)
        self.failure = failure
