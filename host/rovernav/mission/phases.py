"""What a mission is doing and how it ended (Phase, Failure, Outcome), the camera fix it is fed
(Detection), and the clock of its exchanges with the rover (resends, silences, deadlines' margins).
"""

from __future__ import annotations

import dataclasses
import enum

# Every exchange is made for a radio that loses frames (protocol/README.md, "Exchanges and
# their retry rules"): a request goes again after RESEND_S, and fails after MAX_TRIES attempts
# made while the rover is heard (an attempt while it is silent does not count: it is carrying
# on alone and answers once the radio is back). At 1 % of bytes lost a signed request and its
# answer get through together about half the time: 30 attempts fail together once in 10^7; 75
# (30 s) give a 5 % radio, where a PATH chunk and its ACK get through together 2 % of the time,
# a fair chance.
RESEND_S = 0.4  # an un-ACKed request goes again after this long
MAX_TRIES = 75  # ... this many times (30 s) while the rover is heard, then the mission fails
HELLO_EVERY_S = 0.25
SILENT_S = 1.0  # no frame from the rover for this long: the radio is down
CLOSE_S = 10.0  # an ended mission's STOP is re-sent until ACKed, for at most this long
LINK_LOG_S = 1.0  # the link's quality goes to the run log this often
HEARD_RECENTLY_S = 5.0  # a rover heard this recently is alive, if the radio is lossy
HELLO_ALIVE_FACTOR = 4  # no HELLO from a rover that is heard: the deadline is this many times longer
MAP_CHECK_S = 2.0  # the map changed and no SCAN_DONE came this long after: check the path anyway
# Frames handled in one tick at most: the rest wait for the next (at 57,600 baud about 100 frames
# arrive a second; a flood on a faster line must not starve the heartbeat and the deadlines).
MAX_FRAMES_PER_TICK = 256


class Phase(enum.Enum):
    HELLO = "hello"  # waiting for the rover's HELLO
    CONFIGURE = "configure"  # sending parameters
    LOCATE = "locate"  # waiting for the camera to see the rover
    LOAD = "load"  # a path is being sent
    RUN = "run"  # the rover follows the path
    DONE = "done"
    FAILED = "failed"


class Failure(enum.Enum):
    """Why a mission failed, as a kind a caller can act on (the message says it in words)."""

    NO_HELLO = "no_hello"  # the rover never said HELLO
    SCHEMA = "schema"  # the rover was built from another protocol definition
    NOT_CONFIGURED = "not_configured"  # parameters not acknowledged in time
    NO_CAMERA = "no_camera"  # the camera does not see the rover
    NOT_LOADED = "not_loaded"  # a path and START not acknowledged in time
    REFUSED = "refused"  # the rover NACKed a command
    NOT_ANSWERED = "not_answered"  # a request unanswered after every try
    ROVER_FAULT = "rover_fault"  # the rover reported a fault (its gyro, ...)
    SILENT = "silent"  # no frame from the rover for too long
    LEG_LATE = "leg_late"  # a leg not reached after its recoveries
    NO_PATH = "no_path"  # the planner's verdict: the goal cannot be reached
    FROM_OUTSIDE = "from_outside"  # ended by whoever runs the mission (a crash, an operator)


class Outcome(enum.Enum):
    RUNNING = "running"
    REACHED = "reached"  # every leg reached
    NO_PATH = "no_path"  # the planner says the goal cannot be reached on what is known
    FAILED = "failed"  # anything else: a refusal, a fault, silence, a deadline


@dataclasses.dataclass
class Detection:
    """A camera fix of the rover in arena coordinates (None fields: the rover was not seen)."""

    t_s: float
    x_m: float | None
    y_m: float | None
    heading_deg: float | None
    reason: str | None = None
