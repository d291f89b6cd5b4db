"""The host's exceptions: one small tree, so a caller can catch exactly what it can handle.

    RovernavError
     ├── InputError (also a ValueError)   a file, flag or value the user gave cannot be used:
     │    ├── ConfigError                  rovernav.config
     │    ├── ScenarioError                rovernav.scenario
     │    ├── MapFileError                 a learned-map file
     │    └── LogFileError, KeyFileError, ArenaError, TrialsError, PortSpecError
     ├── LinkError                         the radio or the rover (rovernav.link.errors), ProvisionError
     ├── CameraError                       a camera that cannot be opened or stops delivering
     ├── PlanningError                     no path: NoPathError and its kinds (rovernav.planning.errors),
     │                                     an arena generator that found no draw
     ├── SetupError                        a tool or a build this machine lacks (the firmware core's
     │                                     library, the Uno image, simavr, `rovernav demo`'s toolchain)
     └── MissionFailed                     a mission that cannot go on (the kind in .failure)

The command line turns MissionFailed into exit status 1 and every other RovernavError into 2, with
its message on one line.
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


class PlanningError(RovernavError):
    """No path: the planner's verdict (NoPathError and its kinds) or an arena nobody could plan."""


class SetupError(RovernavError):
    """Something this machine must have to do the work is missing or does not build (one line
    naming it, and what to install)."""


class MissionFailed(RovernavError):
    """The mission cannot go on: the rover refused it, faulted, stopped answering, or no path exists.
    `failure` is the kind (rovernav.mission.Failure), when the mission said it."""

    def __init__(self, message: str, failure=None):
        super().__init__(message)
        self.failure = failure
