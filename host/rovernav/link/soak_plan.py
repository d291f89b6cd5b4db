"""What `rovernav link-check --soak` (link/soak.py) sends and how often, how long it waits, and
the paths it loads (see soak.py's docstring for what each measures)."""

from __future__ import annotations

import random

from . import messages_gen as mg

#: The round-trip probe: a CONFIG naming no parameter, which the rover refuses (NACK
#: unknown_param, the same sequence number) without changing anything.
PROBE_PARAM = 0
assert PROBE_PARAM not in {int(p) for p in mg.PARAMS}, "the probe must name no parameter"
PROBE_HZ = 5.0
PROBE_TIMEOUT_S = 2.0  # a probe unanswered this long is lost
HEARTBEAT_S = 0.2  # as link-check
PATH_WAYPOINTS = 32
PATH_EVERY_S = 5.0  # a path load starts this long after the last one ended
PATH_FIRST_S = 1.0  # ... and the first this long into the soak (after a STATUS)
PATH_RESEND_S = 0.4  # the mission's RESEND_S (rovernav.mission.phases)
PATH_GIVE_UP_S = 30.0  # a load not complete after this long is given up (and counted)
PROGRESS_S = 5.0  # a progress line this often
SILENT_S = 1.0  # no frame from the rover this long: a silence (the mission's SILENT_S)
MIN_SOAK_S, MAX_SOAK_S = 1.0, 86_400.0
#: Fewer frames than this one way, and the share lost is a rough figure: the report says so.
FEW_FRAMES = 200
#: The seed's arena (rovernav.config.ArenaConfig), less a margin: where the soak's waypoints lie [mm].
ARENA_MM = ((150, 2200), (150, 1600))

WAYS = {"host_to_rover": "host -> rover", "rover_to_host": "rover -> host"}


def soak_waypoints(index: int) -> list[tuple[int, int]]:
    """The `index`-th soak path: PATH_WAYPOINTS points inside the arena (non-negative mm), a new
    set each time (never driven: no START is sent)."""
    rng = random.Random(index)
    (x0, x1), (y0, y1) = ARENA_MM
    return [(rng.randrange(x0, x1), rng.randrange(y0, y1)) for _ in range(PATH_WAYPOINTS)]
