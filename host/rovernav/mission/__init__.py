"""The host's side of a run, the same against the simulator and the radio.

    core.py          Mission: phases with deadlines, legs, what the rover says
    legs.py          Leg, Deadlines, leg goals, the record of legs done
    interface.py     MissionView and Strategy: what the mission and a strategy see of each other
    strategies.py    how a leg is driven: rovernav's strategy and the 2019 seed's
Requests and their resends are the link's (rovernav.link.requests), shared with Link.request;
the learned map (the sonar's echoes folded into the planner's grid) is rovernav.mapping's.
"""
from ..errors import MissionFailed
from .core import Detection, Failure, Mission, Outcome, Phase
from .interface import MissionView, Strategy
from .legs import Deadlines, Leg, leg_goal, leg_origin, legs_per_trip
from .strategies import RovernavStrategy, SeedStrategy, make_strategy

__all__ = ["Deadlines", "Detection", "Failure", "Leg", "Mission", "MissionFailed", "MissionView", "Outcome", "Phase",
           "RovernavStrategy", "SeedStrategy", "Strategy", "leg_goal", "leg_origin", "legs_per_trip", "make_strategy"]
