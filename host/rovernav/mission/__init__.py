"""The host's side of a run, the same against the simulator and the radio.

    core.py          Mission: phases with deadlines, legs, requests and paths sent
    rover_frames.py  ... what the rover says, and what the mission does about it (a base of Mission)
    leg_control.py   ... its legs: started, resumed, watched, replanned (another base of Mission)
    leg_plan.py      a leg's path on what the host knows (fallbacks, turns, backing out)
    phases.py        Phase, Failure, Outcome, Detection, the exchanges' timings
    recorder.py      Recorder: what a mission tells a run log
    legs.py          Leg, Deadlines, leg goals, the record of legs done
    interface.py     MissionView and Strategy: what the mission and a strategy see of each other
    strategies.py    how a leg is driven: rovernav's strategy and the 2019 seed's
    spec.py          MissionSpec: what a Mission is made from, in plain values

Requests and their resends are the link's (rovernav.link.requests), shared with Link.request;
the learned map (the sonar's echoes folded into the planner's grid) is rovernav.mapping's.
"""

from ..errors import MissionFailed
from .core import Mission
from .interface import MissionView, Strategy
from .legs import Deadlines, Leg, leg_goal, leg_origin, legs_per_trip
from .phases import Detection, Failure, Outcome, Phase
from .strategies import RovernavStrategy, SeedStrategy, make_strategy

__all__ = [
    "Deadlines",
    "Detection",
    "Failure",
    "Leg",
    "Mission",
    "MissionFailed",
    "MissionView",
    "Outcome",
    "Phase",
    "RovernavStrategy",
    "SeedStrategy",
    "Strategy",
    "leg_goal",
    "leg_origin",
    "legs_per_trip",
    "make_strategy",
]
