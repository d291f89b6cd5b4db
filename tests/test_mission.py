"""The mission loop over the real protocol (frames on an in-process pipe): against the firmware core
itself (its C ABI, stepped in simulated time) wherever the rover behaves as its firmware does, and
against a scripted rover only for what the real one never does (another protocol definition, a
refusal, silence, arrivals early or lost)."""

from __future__ import annotations

import math

import pytest
from tests.core_transport import CoreRover, firmware_hello

from rovernav.errors import MapFileError
from rovernav.link import framing
from rovernav.link import messages_gen as mg
from rovernav.link.link import Link
from rovernav.link.transport import PipeTransport
from rovernav.mission import Detection, Failure, Mission, Outcome, Phase, phases
from rovernav.mission.leg_plan import PlannedPath
from rovernav.mission.legs import Leg, path_length_m, round_trips_done
from rovernav.planning import OccupancyGrid, PlannerConfig
from rovernav.planning.turns import body_clear


class ScriptedRover:
    """Answers like the firmware: HELLO, ACK per command, PATH_ACCEPTED when a path is complete."""

    def __init__(self, end, schema=mg.SCHEMA_HASH, boot_id=11, nack_start=None):
        self.end, self.schema, self.boot_id, self.nack_start = end, schema, boot_id, nack_start
        self.decoder = framing.FrameDecoder()
        self.seq = 0
        self.got: list = []
        self.paths: dict[int, list] = {}
        self.started: list[int] = []

    def say(self, m):
        self.end.write(framing.encode_frame(m, self.seq))
        self.seq = (self.seq + 1) & 0xFF

    def hello(self):
        self.say(firmware_hello(schema_hash=self.schema, boot_id=self.boot_id))

    def serve(self, t_s=None):
        for f in self.decoder.feed(self.end.read(65536, 0)):
            m = f.message
            self.got.append(m)
            if isinstance(m, mg.Hello):
                self.hello()
            elif isinstance(m, mg.Config):
                self.say(mg.Ack(msg_id=m.ID, seq=f.seq))
            elif isinstance(m, mg.Path):
                pts = self.paths.setdefault(m.path_id, [])
                pts += [(m.x_mm[i] / 1000, m.y_mm[i] / 1000) for i in range(m.count)]
                self.say(mg.Ack(msg_id=m.ID, seq=f.seq))
                if len(pts) == m.total:
                    self.say(mg.Event(kind=mg.EventKind.PATH_ACCEPTED, arg=m.path_id))
            elif isinstance(m, mg.Start):
                if self.nack_start is not None:
                    self.say(mg.Nack(msg_id=m.ID, seq=f.seq, reason=self.nack_start, detail=0))
                else:
                    self.started.append(m.path_id)
                    self.say(mg.Ack(msg_id=m.ID, seq=f.seq))

    def of(self, cls):
        return [m for m in self.got if isinstance(m, cls)]


def _setup(legs=1, rover_cls=None, **rover_kw):
    host_end, rover_end = PipeTransport.pair()
    rover = (rover_cls or (ScriptedRover if rover_kw else CoreRover))(rover_end, **rover_kw)
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    notes = []
    mission = Mission(
        Link(host_end),
        grid,
        (0.3, 0.3),
        (2.0, 1.4),
        legs=legs,
        rover_params=[(mg.Param.DRIVE_PWM, 80)],
        on_event=lambda t, text: notes.append(text),
    )
    return mission, rover, notes


def _run(mission, rover, seconds, pose=(0.3, 0.3, 0.0), t0=0.0, step=0.03):
    t = t0
    while t < t0 + seconds and not mission.done:
        mission.on_detection(Detection(t - 0.04, *pose), t)
        mission.tick(t)
        rover.serve(t)
        t += step
    return t


def test_a_mission_configures_plans_loads_the_path_starts_and_streams_fixes():
    mission, rover, notes = _setup()
    _run(mission, rover, 2.0)
    assert mission.phase is Phase.RUN
    geometry = PlannerConfig()
    assert [(c.param, c.value) for c in rover.of(mg.Config)] == [
        (mg.Param.ROBOT_RADIUS_MM, round(geometry.robot_radius_m * 1000)),
        (mg.Param.SONAR_MARGIN_MM, round(geometry.sonar_margin_m * 1000)),
        (mg.Param.SONAR_OFFSET_MM, round(geometry.sonar_offset_m * 1000)),
        (mg.Param.SONAR_CONE_CDEG, round(geometry.sonar_cone_deg * 100)),
        (mg.Param.DRIVE_PWM, 80),
    ]
    # The firmware took the path and START: it is under way (sweeping first, then turning or driving).
    assert [m.path_id for m in rover.of(mg.Start)] == [mission.path_id]
    assert rover.state in (mg.RoverState.SCAN, mg.RoverState.ROTATE, mg.RoverState.DRIVE)
    path = rover.paths[mission.path_id]
    assert math.dist(path[0], (0.3, 0.3)) < 0.01 and math.dist(path[-1], (2.0, 1.4)) < 0.01
    fixes = rover.of(mg.Fix)
    assert len(fixes) > 50 and fixes[-1].x_mm == 300 and 30 <= fixes[-1].age_ms <= 50
    assert rover.of(mg.Heartbeat)


def test_an_obstacle_that_blocks_the_path_triggers_one_replan_after_the_sweep():
    mission, rover, notes = _setup()
    t = _run(mission, rover, 1.0)
    first = mission.path_id
    # The rover, at (0.8, 0.6) heading for the target, sees something 0.3 m straight ahead.
    heading = math.degrees(math.atan2(2.0 - 0.8, 1.4 - 0.6))
    for bearing in (-1500, 0, 1500):
        rover.say(
            mg.Obstacle(
                scan_id=1,
                bearing_cdeg=bearing,
                range_mm=300,
                x_mm=800,
                y_mm=600,
                heading_cdeg=round(heading * 100),
                sd_mm=3,
            )
        )
    rover.say(mg.Event(kind=mg.EventKind.SCAN_DONE, arg=3))
    _run(mission, rover, 1.0, pose=(0.8, 0.6, heading), t0=t)
    assert mission.replans == 1 and mission.path_id == first + 1
    assert not mission.grid.path_blocked(rover.paths[mission.path_id][1:])


def test_out_and_back_sends_the_rover_home_after_arrival():
    mission, rover, notes = _setup(legs=2)
    t = _run(mission, rover, 1.0)
    rover.say(mg.Event(kind=mg.EventKind.ARRIVED, arg=1))
    t = _run(mission, rover, 1.0, pose=(2.0, 1.4, 45.0), t0=t)
    assert len(mission.legs) == 2 and mission.legs[0].reached
    home = rover.paths[mission.path_id]
    assert math.dist(home[-1], (0.3, 0.3)) < 0.01 and len(rover.of(mg.Start)) == 2
    rover.say(mg.Event(kind=mg.EventKind.ARRIVED, arg=1))
    _run(mission, rover, 0.5, pose=(0.3, 0.3, 200.0), t0=t)
    assert mission.phase is Phase.DONE and rover.of(mg.Stop)


def test_a_rover_from_another_protocol_definition_fails_the_mission_with_both_hashes():
    mission, rover, notes = _setup(schema=0x12345678)
    _run(mission, rover, 1.0)
    assert mission.phase is Phase.FAILED and mission.failure is Failure.SCHEMA
    assert (mission.cause.ours, mission.cause.theirs) == (mg.SCHEMA_HASH, 0x12345678)


def test_a_nack_fails_the_mission_with_the_rovers_reason():
    mission, rover, notes = _setup(nack_start=mg.NackReason.FAULTED)
    _run(mission, rover, 2.0)
    assert mission.phase is Phase.FAILED and mission.failure is Failure.REFUSED
    assert mission.cause.reason == mg.NackReason.FAULTED


def test_a_rover_that_hears_but_does_not_answer_fails_the_mission_after_the_retries():
    mission, rover, notes = _setup(rover_cls=ScriptedRover)
    t = 0.0
    while t < 40 and not mission.done:  # HELLO is answered; then STATUS comes, but no ACK
        mission.on_detection(Detection(t, 0.3, 0.3, 0.0), t)
        mission.tick(t)
        if t < 0.1:
            rover.serve()
        else:
            rover.end.read(65536, 0)
            rover.say(mg.Status(time_ms=int(t * 1000)))
        t += 0.05
    # The request's attempts, or the phase's deadline, whichever ends first: both name it.
    assert mission.phase is Phase.FAILED and mission.failure in (Failure.NOT_ANSWERED, Failure.NOT_LOADED)
    # Counted in attempts and time: a lossy link that answers now and then is given 30 s.
    assert t >= min((phases.MAX_TRIES - 1) * phases.RESEND_S, mission.deadlines.load_s)


def test_a_silent_rover_is_waited_for_then_given_up_on():
    mission, rover, notes = _setup(rover_cls=ScriptedRover)
    t = 0.0
    while t < 200 and not mission.done:  # HELLO is answered, then nothing: the radio is down
        mission.on_detection(Detection(t, 0.3, 0.3, 0.0), t)
        mission.tick(t)
        if t < 0.1:
            rover.serve()
        else:
            rover.end.read(65536, 0)
        t += 0.25
    assert mission.phase is Phase.FAILED and mission.failure is Failure.SILENT
    assert mission.deadlines.silent_s < t < mission.deadlines.silent_s + 5


def test_a_rebooted_rover_is_sent_its_parameters_and_path_again():
    mission, rover, notes = _setup()
    t = _run(mission, rover, 2.0)
    configs = len(rover.of(mg.Config))
    rover.reboot(boot_id=99)  # the firmware restarts: its boot HELLO, no parameters, no path
    t = _run(mission, rover, 2.0, t0=t)
    assert mission.rover_boot_id == 99 and mission.phase is Phase.RUN
    assert len(rover.of(mg.Config)) == 2 * configs == 2 * len(mission.rover_params)
    assert rover.of(mg.Start)[-1].path_id == mission.path_id and len(rover.of(mg.Start)) >= 2
    assert rover.state in (mg.RoverState.SCAN, mg.RoverState.ROTATE, mg.RoverState.DRIVE)


def test_the_learned_map_is_saved_and_loaded(tmp_path):
    mission, rover, _ = _setup()
    t = _run(mission, rover, 1.0)
    rover.say(mg.Obstacle(scan_id=1, bearing_cdeg=0, range_mm=250, x_mm=1000, y_mm=800, heading_cdeg=0, sd_mm=3))
    _run(mission, rover, 0.3, t0=t)
    mission.save_map(tmp_path / "map.json")
    fresh, _, _ = _setup()
    assert fresh.load_map(tmp_path / "map.json") == 1
    assert (fresh.grid.raw == mission.grid.raw).all()
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(MapFileError, match="not a rovernav map"):
        fresh.load_map(tmp_path / "bad.json")


# ---------------------------------------------------------------- arrivals the host must not lose


class ArrivingRover(ScriptedRover):
    """Arrives as soon as it is started (a leg that is nearly done), before the host has seen
    START's ACK move it to its running phase; optionally the ARRIVED event is lost and only
    STATUS (state arrived on that path) tells."""

    def __init__(self, end, lose_event=False, **kw):
        super().__init__(end, **kw)
        self.lose_event = lose_event

    def serve(self, t_s=None):
        before = len(self.started)
        super().serve(t_s)
        for path_id in self.started[before:]:
            if self.lose_event:
                self.say(mg.Status(time_ms=1, state=mg.RoverState.ARRIVED, path_id=path_id))
            else:
                self.say(mg.Event(kind=mg.EventKind.ARRIVED, arg=1))


def _setup_with(rover_cls, start=(0.3, 0.3), target=(2.0, 1.4), legs=1, grid=None, **kw):
    host_end, rover_end = PipeTransport.pair()
    rover = rover_cls(rover_end, **kw)
    notes = []
    mission = Mission(
        Link(host_end),
        grid or OccupancyGrid(2.36, 1.75, PlannerConfig()),
        start,
        target,
        legs=legs,
        on_event=lambda t, text: notes.append(text),
    )
    return mission, rover, notes


@pytest.mark.parametrize("lose_event", [False, True])
def test_an_arrival_that_comes_before_the_host_expects_it_is_not_lost(lose_event):
    mission, rover, _ = _setup_with(ArrivingRover, lose_event=lose_event)
    t = _run(mission, rover, 3.0)
    assert mission.phase is Phase.DONE and mission.outcome is Outcome.REACHED
    assert mission.legs[0].reached and len(rover.started) == 1 and t < 1.0


def test_a_leg_that_is_done_at_once_is_done_without_moving_the_rover():
    mission, rover, notes = _setup_with(CoreRover, start=(0.3, 0.3), target=(0.32, 0.3))
    _run(mission, rover, 2.0)
    assert mission.phase is Phase.DONE and mission.outcome is Outcome.REACHED
    assert rover.of(mg.Start) == [] and rover.of(mg.Path) == [] and mission.legs[0].reached


def test_a_status_from_before_start_is_not_taken_for_an_arrival():
    # The rover still reports ARRIVED from its last path while the new one loads: no false arrival.
    mission, rover, _ = _setup_with(ScriptedRover, legs=2)
    t = _run(mission, rover, 0.5)
    assert mission.phase in (Phase.LOAD, Phase.RUN)
    rover.say(mg.Status(time_ms=1, state=mg.RoverState.ARRIVED, path_id=mission.path_id + 1))
    rover.say(mg.Status(time_ms=1, state=mg.RoverState.ARRIVED, path_id=mission.path_id - 1))
    _run(mission, rover, 0.5, t0=t)
    assert not mission.legs[0].reached


# ---------------------------------------------------------------- every phase has a deadline


def _run_until_done(mission, rover, seconds, seen=True, answer=True):
    t = 0.0
    while t < seconds and not mission.done:
        if seen:
            mission.on_detection(Detection(t - 0.04, 0.3, 0.3, 0.0), t)
        mission.tick(t)
        if answer:
            rover.serve()
            rover.say(mg.Status(time_ms=int(t * 1000), state=mg.RoverState.DRIVE, path_id=mission.path_id))
        else:
            rover.end.read(65536, 0)
        t += 0.1
    return t


def test_a_rover_that_never_says_hello_fails_the_mission_at_the_hello_deadline():
    mission, rover, _ = _setup_with(ScriptedRover)
    t = _run_until_done(mission, rover, 600, answer=False)
    assert mission.phase is Phase.FAILED and mission.failure is Failure.NO_HELLO
    assert mission.deadlines.hello_s <= t <= mission.deadlines.hello_s + 1


def test_a_rover_the_camera_never_sees_fails_the_mission_at_the_locate_deadline():
    mission, rover, _ = _setup_with(ScriptedRover)
    t = _run_until_done(mission, rover, 600, seen=False)
    assert mission.phase is Phase.FAILED and mission.failure is Failure.NO_CAMERA
    assert t <= mission.deadlines.locate_s + 2


def test_a_leg_never_reached_is_replanned_then_fails_within_its_deadlines():
    mission, rover, notes = _setup_with(ScriptedRover)
    t = _run_until_done(mission, rover, 3000)
    d = mission.deadlines
    leg = mission.legs[0]
    assert mission.phase is Phase.FAILED and mission.failure is Failure.LEG_LATE
    assert leg.recoveries == d.leg_recoveries and len(rover.started) == 1 + d.leg_recoveries
    assert t <= (1 + d.leg_recoveries) * d.leg_s(leg.planned_length_m) + 5


def test_a_fleets_rover_late_to_its_site_gives_up_its_trips_and_goes_home_to_wait_not_in_the_way():
    # A fleet's rover (parked at home when its trips are done) whose leg to its site is late after
    # its recoveries: its mission goes on, with a leg home (here: done at once, the camera sees it
    # at its berth) and it waits there with the fleet; once the fleet is done its mission ends
    # failed, saying why, with no trip counted.
    mission, rover, notes = _setup_with(ScriptedRover, legs=4)
    mission.park_at_end = True
    _run_until_done(mission, rover, 1500)
    assert not mission.done and mission.parked and mission.gave_up is not None
    assert [leg.reached for leg in mission.legs] == [False, False] and mission.legs[1].goal == (0.3, 0.3)
    assert any("gives up its trips" in n for n in notes) and round_trips_done(mission.legs, mission.parked) == 0
    mission.release_park(1500.0)
    assert mission.done and mission.outcome is Outcome.FAILED and mission.failure is Failure.LEG_LATE
    assert mission.error.startswith("leg 1 not reached after")


def test_a_fleets_rover_whose_site_is_where_it_stands_does_its_trip_once_and_waits_parked():
    # A site within the arrival radius of the rover's berth: both legs are done where it stands,
    # before any path, and it parks with the fleet (not a new leg every tick while it locates).
    mission, rover, notes = _setup_with(ScriptedRover, target=(0.32, 0.31), legs=2)
    mission.park_at_end = True
    _run_until_done(mission, rover, 30)
    assert len(mission.legs) == 2 and mission.parked and mission.phase is Phase.RUN and not mission.done
    assert [leg.reached for leg in mission.legs] == [True, False]
    assert sum("already within" in n for n in notes) == 2
    mission.release_park(30.0)
    assert mission.done and mission.outcome is Outcome.REACHED and round_trips_done(mission.legs) == 1


def test_round_trips_count_only_a_site_and_home_both_reached():
    def legs(*reached):
        return [Leg(index=i, goal=(0.0, 0.0), started_s=0.0, reached=r) for i, r in enumerate(reached)]

    assert round_trips_done(legs(True, True, True, True)) == 2
    assert round_trips_done(legs(True, True, False, True)) == 1  # the second site given up, home after it
    assert round_trips_done(legs(True, True, True, False), home_at_last=True) == 2  # parked at home
    assert round_trips_done(legs(True, False)) == 0 and round_trips_done([]) == 0


def test_an_enclosed_target_ends_the_mission_with_the_no_path_verdict():
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    for x, y, w, h in ((2.0, 1.15, 0.5, 0.05), (2.0, 1.65, 0.5, 0.05), (1.75, 1.4, 0.05, 0.5), (2.25, 1.4, 0.05, 0.5)):
        grid.add_box(x, y, w, h)
    mission, rover, _ = _setup_with(ScriptedRover, target=(2.0, 1.4), grid=grid)
    _run_until_done(mission, rover, 60)
    assert mission.phase is Phase.FAILED and mission.outcome is Outcome.NO_PATH and mission.failure is Failure.NO_PATH


def test_results_are_written_whole_and_readable_as_an_ordinary_file(tmp_path):
    import os
    import stat

    from rovernav.files import write_atomic

    target = tmp_path / "report.json"
    target.write_text("old")
    write_atomic(target, '{"new": true}\n')
    assert target.read_text() == '{"new": true}\n'
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]  # no temporary file left behind


def test_a_path_longer_than_the_rover_holds_goes_in_parts_and_the_leg_ends_at_its_true_end():
    mission, rover, notes = _setup(rover_cls=ScriptedRover)
    t = _run(mission, rover, 1.0)
    assert mission.phase is Phase.RUN
    # A winding path of 40 waypoints (as a cluttered arena's A* can give), ending at the target.
    zigzag = [(0.3 + 0.04 * i, 0.3 + (0.05 if i % 2 else 0.0)) for i in range(39)] + [(2.0, 1.4)]
    mm = lambda pts: [(round(x * 1000), round(y * 1000)) for x, y in pts]  # noqa: E731 - as the wire carries them
    mission.load_path(zigzag)
    t = _run(mission, rover, 1.0, t0=t)
    assert mm(rover.paths[mission.path_id]) == mm(zigzag[: mg.MAX_WAYPOINTS]) and mission.phase is Phase.RUN
    rover.say(mg.Event(kind=mg.EventKind.ARRIVED, arg=1))  # at the end of the first part
    t = _run(mission, rover, 1.0, t0=t)
    assert mm(rover.paths[mission.path_id]) == mm(zigzag[mg.MAX_WAYPOINTS - 1 :])
    assert not mission.legs[0].reached and mission.phase is Phase.RUN
    rover.say(mg.Event(kind=mg.EventKind.ARRIVED, arg=1))  # at the target
    _run(mission, rover, 1.0, t0=t)
    assert mission.legs[0].reached and mission.phase is Phase.DONE


def test_a_goal_an_echo_s_arc_covers_is_reached_from_beside_it_but_a_wall_is_not_crossed():
    # The home the rover left, beside a known box whose corner echoed at the cone's edge: the
    # arc's cells lie 0.10 m from the goal, inside even the robot radius. The last tries plan to
    # the nearest free cell within GOAL_SHIFT_M and then straight on to the goal.
    from rovernav.mapping import SonarReading
    from rovernav.mission import leg_plan

    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(1.6, 0.4))
    mission.map.add(SonarReading(1.25, 0.4, 90.0, 0.0, 0.15, 0.6))  # an arc at x 1.50 (sensor at 1.35)
    assert not mission.map.lenient_grid().is_free(1.6, 0.4) and mission.map.known_grid.is_free(1.6, 0.4)
    path = mission.plan_from((0.3, 0.3), (1.6, 0.4))
    assert path is not None and path[-1] == (1.6, 0.4)
    assert 0 < math.dist(path[-2], path[-1]) <= leg_plan.GOAL_SHIFT_M + 1e-9
    assert any("within an echo's arc" in n for n in notes)
    # A target that a known box's margin covers is not shifted: the verdict stands.
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    grid.add_box(1.6, 0.55, 0.3, 0.1)
    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(1.6, 0.4), grid=grid)
    assert mission.plan_from((0.3, 0.3), (1.6, 0.4)) is None


@pytest.mark.parametrize("backed_to, replans", [((1.17, 0.50), 1), ((1.30, 0.45), 0)])
def test_a_rover_that_backed_out_is_sent_a_new_path_when_its_line_on_would_scrape(backed_to, replans):
    # The path passes below a box and turns up beside it; the rover refused the turn there and
    # backed out. From where it stopped, the straight line to its next waypoint runs 0.025 m
    # from the box's face (its sides need 0.085 m): the host replans. From 0.15 m off, it does not.
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    grid.add_box(1.0, 0.8, 0.3, 0.3)  # x 0.85..1.15, y 0.65..0.95
    mission, rover, notes = _setup_with(ScriptedRover, start=(0.6, 0.5), target=(1.3, 1.4), grid=grid)
    t = _run(mission, rover, 1.5, pose=(0.6, 0.5, 90.0))
    assert mission.phase is Phase.RUN
    mission.load_path([(0.6, 0.5), (1.3, 0.5), (1.3, 1.4)])
    t = _run(mission, rover, 0.5, pose=(0.6, 0.5, 90.0), t0=t)
    flags = int(mg.StatusFlag.SCHEMA_OK | mg.StatusFlag.MISSION_ACTIVE | mg.StatusFlag.PATH_LOADED)
    x_mm, y_mm = round(backed_to[0] * 1000), round(backed_to[1] * 1000)
    for state in (mg.RoverState.BACK_OFF, mg.RoverState.ROTATE):
        rover.say(
            mg.Status(
                state=int(state),
                flags=flags,
                path_id=mission.path_id,
                waypoint_index=2,
                x_mm=x_mm,
                y_mm=y_mm,
                heading_cdeg=9000,
            )
        )
        t = _run(mission, rover, 0.2, pose=(*backed_to, 90.0), t0=t)
    assert mission.replans == replans
    if replans:
        assert body_clear(mission.grid, mission.path[0], mission.path[1])
        assert any(n.startswith("the line on from where the rover backed out scrapes: replanned") for n in notes)


def test_a_turn_refused_twice_in_one_spot_is_not_planned_there_again():
    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(2.0, 1.4))
    t = _run(mission, rover, 1.5)
    assert mission.phase is Phase.RUN
    leg = mission.current_leg
    for x_mm in (1000, 1020):
        rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=x_mm, y_mm=800))
        t = _run(mission, rover, 0.1, t0=t)
    rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=1500, y_mm=500))
    _run(mission, rover, 0.1, t0=t)
    assert leg.turns_refused_at == [(1.0, 0.8), (1.02, 0.8), (1.5, 0.5)]
    assert leg.refused_twice() == [(1.0, 0.8), (1.02, 0.8)]  # once is not enough


def test_a_fleet_rover_that_refuses_a_turn_is_held_at_once_and_planned_from_where_it_stops():
    # A lone rover backs out on its own (its host replans on hearing it has); a fleet's rover is
    # stopped as it begins to (hold_on_refused), left standing REFUSED_SETTLE_S, and its first turn
    # from there is checked against where it refused.
    from rovernav.mission.fleet_control import REFUSED_SETTLE_S

    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(2.0, 1.4))
    t = _run(mission, rover, 1.5)
    assert mission.phase is Phase.RUN
    rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=300, y_mm=300))
    t = _run(mission, rover, 0.2, t0=t)
    assert not mission.held and mission.refusal_holds == 0  # a lone rover's mission: no hold
    mission.hold_on_refused = True
    rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=300, y_mm=300))
    t = _run(mission, rover, 0.2, t0=t)
    assert mission.held and mission.refusal_holds == 1
    assert rover.of(mg.Stop)  # the STOP went
    assert any(n.startswith("held: refused a turn") for n in notes)
    assert mission.settling(t) and not mission.settling(t + REFUSED_SETTLE_S)
    assert mission.current_leg.turns_refused_at == [(0.3, 0.3), (0.3, 0.3)]
    # Refused there again and again (REFUSALS_HELD and more): it backs out on its own.
    from rovernav.mission.fleet_control import REFUSALS_HELD

    mission._held_since = None  # (let go)
    for k in range(REFUSALS_HELD):
        rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=300 + 10 * k, y_mm=300))
        t = _run(mission, rover, 0.2, t0=t)
        mission._held_since = None
    assert mission.refusal_holds == REFUSALS_HELD - 1  # from the fourth near there on, none held


def test_a_fleet_rover_backing_out_on_the_hosts_word_is_not_held_for_it():
    # A path that asks the rover to back out (PATH back_out): the rover says TURN_REFUSED as it
    # begins the back-out the host asked for, which goes on; a second refusal on it is held.
    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(2.0, 1.4))
    mission.hold_on_refused = True
    t = _run(mission, rover, 1.5)
    mission.load_path(PlannedPath([(0.3, 0.3), (0.8, 0.9)], back_out=True))
    t = _run(mission, rover, 1.5, t0=t)
    assert rover.of(mg.Path)[-1].back_out == 1 and mission.phase is Phase.RUN and not mission.held
    for held in (False, True):
        rover.say(mg.Event(kind=int(mg.EventKind.TURN_REFUSED), arg=60, x_mm=300, y_mm=300))
        t = _run(mission, rover, 0.2, t0=t)
        assert mission.held is held
    assert mission.refusal_holds == 1


def test_a_check_that_finds_no_way_is_no_verdict():
    # The target walled in: the leg's planning says 'no path' and ends the mission; a check (after
    # a back-off) that finds no way from where the rover stands keeps the path it has.
    grid = OccupancyGrid(2.36, 1.75, PlannerConfig())
    for box in ((1.6, 1.15, 0.6, 0.05), (1.6, 0.65, 0.6, 0.05), (1.3, 0.9, 0.05, 0.55), (1.9, 0.9, 0.05, 0.55)):
        grid.add_box(*box)
    mission, rover, notes = _setup_with(ScriptedRover, start=(0.3, 0.3), target=(1.6, 0.9), grid=grid)
    assert mission.plan_from((0.3, 0.3), (1.6, 0.9), verdict=False) is None
    assert mission.phase is not Phase.FAILED and mission.failure is None
    assert mission.plan_from((0.3, 0.3), (1.6, 0.9)) is None
    assert mission.phase is Phase.FAILED and mission.failure is Failure.NO_PATH


def test_a_path_from_where_the_rover_stands_without_room_to_turn_starts_straight_ahead():
    # The rover stands facing east with a box's corner 0.11 m off its right rear (the half-diagonal
    # is 0.129 m); its new path turns it north. The host puts in a point straight ahead, where it
    # has room, and says so. Facing north already, the turn is small: nothing goes in.
    from rovernav.planning.turns import SWING_M, SWING_MARGIN_M, clearance_map

    grid = OccupancyGrid(2.36, 1.75, PlannerConfig(sonar_margin_m=0.0))
    grid.add_box(0.95, 0.64, 0.1, 0.1)  # x 0.90..1.00, y 0.59..0.69
    mission, rover, notes = _setup_with(ScriptedRover, start=(1.0, 0.8), target=(1.5, 1.5), grid=grid)
    flags = int(mg.StatusFlag.SCHEMA_OK | mg.StatusFlag.MISSION_ACTIVE)
    rover.say(mg.Status(state=int(mg.RoverState.IDLE), flags=flags, x_mm=1000, y_mm=800, heading_cdeg=9000))
    t = _run(mission, rover, 0.3, pose=(1.0, 0.8, 90.0))
    assert mission.rover_heading_deg() == 90.0
    path = mission.plan_from((1.0, 0.8), (1.0, 1.5))
    assert path is not None and path[0] == (1.0, 0.8) and path[-1] == (1.0, 1.5)
    q = path[1]
    assert abs(q[1] - 0.8) < 1e-9 and 0.0 < q[0] - 1.0 <= 0.3  # straight ahead, east
    need = SWING_M + SWING_MARGIN_M
    clear = clearance_map(grid, 1.0)
    ix, iy = grid.world_to_cell(*q)
    assert clear[iy, ix] >= need
    assert any(n.startswith("no room to turn where the rover stands") for n in notes)
    rover.say(mg.Status(state=int(mg.RoverState.IDLE), flags=flags, x_mm=1000, y_mm=800, heading_cdeg=0))
    _run(mission, rover, 0.3, pose=(1.0, 0.8, 0.0), t0=t)
    assert mission.plan_from((1.0, 0.8), (1.0, 1.5))[1] != q


def test_no_room_where_the_rover_stands_and_none_ahead_asks_it_to_back_out_first():
    # As above, with a wall across its way 0.12 m ahead: no point straight ahead. The path goes
    # out as it is, and its PATH chunks ask the rover to back out before it turns (back_out 1);
    # the next path, planned where it has room, does not.
    from rovernav.mission.leg_plan import PlannedPath

    grid = OccupancyGrid(2.36, 1.75, PlannerConfig(sonar_margin_m=0.0))
    grid.add_box(0.95, 0.64, 0.1, 0.1)  # x 0.90..1.00, y 0.59..0.69
    grid.add_box(1.2, 0.8, 0.02, 0.4)  # the wall ahead, x 1.19..1.21
    mission, rover, notes = _setup_with(ScriptedRover, start=(1.0, 0.8), target=(1.5, 1.5), grid=grid)
    flags = int(mg.StatusFlag.SCHEMA_OK | mg.StatusFlag.MISSION_ACTIVE)
    rover.say(mg.Status(state=int(mg.RoverState.IDLE), flags=flags, x_mm=1000, y_mm=800, heading_cdeg=9000))
    _run(mission, rover, 0.3, pose=(1.0, 0.8, 90.0))
    path = mission.plan_from((1.0, 0.8), (1.0, 1.5))
    assert isinstance(path, PlannedPath) and path.back_out
    assert path[0] == (1.0, 0.8) and path[-1] == (1.0, 1.5)
    assert any(n.startswith("no room to turn where the rover stands, none straight ahead") for n in notes)
    mission.load_path(path)
    t = _run(mission, rover, 0.3, pose=(1.0, 0.8, 90.0))
    sent = [m for m in rover.of(mg.Path) if m.path_id == mission.path_id]
    assert sent and all(m.back_out == 1 for m in sent)
    mission.load_path([(1.0, 1.0), (1.0, 1.5)])
    _run(mission, rover, 0.3, pose=(1.0, 1.0, 0.0), t0=t)
    sent = [m for m in rover.of(mg.Path) if m.path_id == mission.path_id]
    assert sent and all(m.back_out == 0 for m in sent)


def test_the_strategies_use_only_what_the_mission_view_declares_and_the_mission_has_it():
    # The strategies talk to the mission through interface.MissionView: every attribute they read
    # on the mission (`m.<name>`) is declared there, and a Mission has every one of them.
    import ast
    import inspect

    from rovernav.mission import interface, strategies

    declared = set(interface.MissionView.__annotations__) | {
        name for name in vars(interface.MissionView) if not name.startswith("_")
    }
    tree = ast.parse(inspect.getsource(strategies))
    used = {
        node.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "m"
    }
    assert used and used <= declared, used - declared
    assert not any(isinstance(node, ast.ImportFrom) and node.module == "core" for node in ast.walk(tree))
    mission, _rover, _notes = _setup_with(ScriptedRover)
    assert all(hasattr(type(mission), name) or hasattr(mission, name) for name in declared - {"current_leg"})
    assert isinstance(inspect.getattr_static(Mission, "current_leg"), property)


def test_a_rover_let_go_where_it_was_held_resumes_without_a_sweep_and_one_carried_off_starts_anew():
    # A fleet's hold (STOP) and let-go (a path from where it stands, START) against the firmware
    # core: START's resume is 1 only when the camera saw the rover stand still since the hold, on a
    # leg it had started; then the rover goes on without the sweep a START otherwise begins with.
    mission, rover, notes = _setup()
    t = _run(mission, rover, 1.0)
    assert mission.phase is Phase.RUN and rover.state == mg.RoverState.SCAN  # a new START sweeps first
    assert rover.of(mg.Start)[-1].resume == 0
    mission.hold(t, "rover 2 is in the way")
    t = _run(mission, rover, 1.0, t0=t)
    assert rover.state == mg.RoverState.IDLE
    mission.let_go(t)
    t = _run(mission, rover, 2.0, t0=t)
    start = rover.of(mg.Start)[-1]
    assert start.path_id == mission.path_id and start.resume == 1
    assert rover.state in (mg.RoverState.ROTATE, mg.RoverState.DRIVE)  # on at once, no sweep
    # Held again, and carried 0.3 m off while it waits: it starts anew, looking first.
    mission.hold(t, "rover 2 is in the way")
    t = _run(mission, rover, 1.0, pose=(0.6, 0.3, 0.0), t0=t)
    mission.let_go(t)
    t = _run(mission, rover, 2.0, pose=(0.6, 0.3, 0.0), t0=t)
    start = rover.of(mg.Start)[-1]
    assert start.path_id == mission.path_id and start.resume == 0
    assert rover.state == mg.RoverState.SCAN


def test_a_rover_that_gave_way_has_at_least_a_whole_legs_time_from_its_spot_aside():
    # Held and let go, a leg's deadline moves by the wait alone; sent aside for another rover, its
    # drive there and back is the traffic's: let go from its spot aside, the leg has at least the
    # time of a leg of the path it is sent from there.
    mission, rover, _ = _setup_with(ScriptedRover)
    t = _run_until_done(mission, rover, 1.0)
    leg = mission.legs[0]
    leg.deadline_s = t + 5.0
    mission.hold(t, "rover 2 is in the way")
    mission.let_go(t + 2.0)
    assert math.isclose(leg.deadline_s, t + 7.0)  # the wait, no more
    mission.hold(t + 2.0, "rover 2 is in the way")
    mission.let_go(t + 3.0, [(0.3, 0.3), (0.3, 0.7)], aside=True)
    assert math.isclose(leg.deadline_s, t + 8.0)
    mission._now = t + 60.0
    assert mission.aside_arrived() and mission.held
    mission.let_go(t + 70.0)
    assert leg.deadline_s >= t + 70.0 + mission.deadlines.leg_s(path_length_m(mission.path)) - 1e-6


def test_a_rover_waiting_at_a_spot_aside_can_be_sent_on_to_another():
    # From its spot aside a rover is let go onto its leg afresh; sent aside again (the traffic
    # rules' make-way for a rover with no way round it), it drives the way it is given, and is
    # held again where that ends.
    mission, rover, _ = _setup_with(ScriptedRover)
    t = _run_until_done(mission, rover, 1.0)
    mission.hold(t, "rover 2 is in the way")
    mission.let_go(t + 1.0, [(0.3, 0.3), (0.3, 0.7)], aside=True)
    mission._now = t + 20.0
    assert mission.aside_arrived() and mission.held
    mission.let_go(t + 30.0, [(0.3, 0.7), (0.7, 0.7)], aside=True)
    assert not mission.held and mission.path[-1] == (0.7, 0.7)  # the way it was given, not its leg
    assert mission.steering_goal() == (0.7, 0.7)
    mission._now = t + 50.0
    assert mission.aside_arrived() and mission.held


def test_a_sweep_heard_in_part_counts_as_heard_whole_over_the_sweeps_from_the_same_spot():
    # Three echoes a sweep, each sweep from the same spot losing one of them on the radio: no
    # sweep alone is heard whole, but a fleet's host (heard_over_spot) gives its word from the
    # second on; a lone rover's host does not. A sweep from elsewhere starts afresh, and a bearing
    # the new sweep says clear no longer counts.
    def sweep(m, scan_id, said, clear=(), at=(800, 600)):
        for b in said:
            m._on_obstacle(
                mg.Obstacle(
                    scan_id=scan_id, bearing_cdeg=b, range_mm=300, x_mm=at[0], y_mm=at[1], heading_cdeg=0, sd_mm=3
                )
            )
        for b in clear:
            m._on_obstacle(
                mg.Obstacle(
                    scan_id=scan_id, bearing_cdeg=b, range_mm=0, x_mm=at[0], y_mm=at[1], heading_cdeg=0, sd_mm=3
                )
            )
        m._scan_done(3)

    for fleet in (False, True):
        mission, rover, notes = _setup()
        mission.heard_over_spot = fleet
        sweep(mission, 1, [-1500, 0])  # +1500 lost
        assert mission.scan_heard == 0
        sweep(mission, 2, [0, 1500])  # -1500 lost: heard over the two
        assert mission.scan_heard == (2 if fleet else 0)
        sweep(mission, 3, [0], clear=[1500])  # +1500 now clear: -1500 and 0 are two, not three
        assert mission.scan_heard == (2 if fleet else 0)
        sweep(mission, 4, [-1500, 0], at=(900, 600))  # elsewhere: afresh
        assert mission.scan_heard == (2 if fleet else 0) and mission.scans_heard_part == (3 if fleet else 4)


def test_a_fleet_rover_drives_over_ground_the_sonar_has_seen_without_its_sweeps_every_0_3_m():
    # sweep_seen_ground: before a path goes, the host checks the ground along it on its map; where
    # every cell near it has been heard clear, the rover is told (CONFIG sweep_interval_mm 0) to
    # drive it without the distance sweeps: once the path is whole on the rover, before its START
    # (a rover still on its last path must not drive the rest of that unswept). For a path over
    # ground not yet seen, the usual interval again, before the path itself. A fleet's configure
    # says the interval whatever the configuration (a rover keeps it from one host to the next);
    # a lone rover's mission sends none of it.
    interval = int(mg.Param.SWEEP_INTERVAL_MM)
    usual = mg.PARAMS[mg.Param.SWEEP_INTERVAL_MM].default
    for fleet in (False, True):
        mission, rover, notes = _setup()
        mission.sweep_seen_ground = fleet
        t = _run(mission, rover, 1.0)
        assert mission.phase is Phase.RUN
        sonar = mission.map.sonar
        sonar.logodds[:] = sonar.model.free_logodds  # every cell heard clear
        mission.load_path([(0.3, 0.3), (1.2, 0.3)])
        t = _run(mission, rover, 1.0, t0=t)
        seen_id = mission.path_id
        sonar.logodds[:] = 0.0  # nothing heard
        mission.load_path([(0.3, 0.3), (1.2, 0.6)])
        t = _run(mission, rover, 1.0, t0=t)
        unseen_id = mission.path_id
        said = [(i, m.value) for i, m in enumerate(rover.got) if isinstance(m, mg.Config) and m.param == interval]
        if not fleet:
            assert said == [] and mission.paths_unswept == 0
            continue
        assert [v for _, v in said] == [usual, 0, usual] and mission.paths_unswept == 1
        got = list(enumerate(rover.got))
        seen_chunks = [i for i, m in got if isinstance(m, mg.Path) and m.path_id == seen_id]
        seen_start = next(i for i, m in got if isinstance(m, mg.Start) and m.path_id == seen_id)
        assert max(seen_chunks) < said[1][0] < seen_start  # 0: the path whole first, START after
        unseen_chunks = [i for i, m in got if isinstance(m, mg.Path) and m.path_id == unseen_id]
        assert said[2][0] < min(unseen_chunks)  # the usual again before the path itself
        assert any("no sweeps on the way" in n for n in notes)
        assert rover.of(mg.Start)[-1].path_id == unseen_id


def test_a_fleet_rover_blocked_on_its_path_with_no_new_one_is_sent_its_leg_again():
    # A rover whose forward reflex stopped it for another rover, and whose own detour found no way,
    # waits Blocked for a new path; the map did not change, so no replan sends one (seed 6: a
    # fleet stuck for good). With resend_blocked_s its leg is planned again after that long, its
    # deadline kept (a re-send is no progress: the late leg's bounded recoveries still decide). A
    # STATUS Blocked on an older path, a rover held for another, or a lone rover's mission: none.
    for watch, held in ((None, False), (9.0, False), (9.0, True)):
        mission, rover, notes = _setup_with(ScriptedRover)
        mission.resend_blocked_s = watch
        t = _run(mission, rover, 1.0)
        assert mission.phase is Phase.RUN
        first, deadline = mission.path_id, mission.current_leg.deadline_s
        if held:
            mission.hold(t, "rover 2 is in the way")
        while t < 20.0:
            mission.on_detection(Detection(t - 0.04, 0.3, 0.3, 0.0), t)
            rover.say(mg.Status(time_ms=int(t * 1000), state=mg.RoverState.BLOCKED, path_id=first - (t < 8.0)))
            mission.tick(t)
            rover.serve(t)
            if mission.path_id != first:
                break
            t += 0.1
        if watch is None or held:
            assert mission.path_id == first and mission.blocked_resends == 0
        else:
            # Blocked on its own path from 8 s: sent again 9 s later, a new path from where it stands.
            assert mission.path_id == first + 1 and mission.blocked_resends == 1 and 16.9 <= t <= 17.2
            assert mission.current_leg.deadline_s == deadline
            assert any("no new path: its leg planned again" in n for n in notes)


def test_what_stopped_the_reflex_is_kept_for_the_leg_only_when_its_echo_was_heard():
    # The rover says the reflex's echo (OBSTACLE) and then REFLEX, its range: the echo's point is kept
    # for the leg (leg_plan.with_margin_round); a REFLEX whose echo was lost, or another range, keeps nothing.
    mission, rover, _ = _setup_with(ScriptedRover)
    t = _run(mission, rover, 1.0)
    assert mission.phase is Phase.RUN and mission.current_leg.stopped_by == []
    rover.say(mg.Event(kind=mg.EventKind.REFLEX, arg=146))  # its echo never came
    t = _run(mission, rover, 0.2, t0=t)
    assert mission.current_leg.stopped_by == []
    echo = dict(scan_id=2, bearing_cdeg=0, x_mm=1000, y_mm=800, heading_cdeg=9000, sd_mm=3)
    rover.say(mg.Obstacle(range_mm=146, **echo))
    rover.say(mg.Event(kind=mg.EventKind.REFLEX, arg=150))  # another range: not this echo's reflex
    t = _run(mission, rover, 0.2, t0=t)
    assert mission.current_leg.stopped_by == []
    rover.say(mg.Obstacle(range_mm=146, **echo))
    rover.say(mg.Event(kind=mg.EventKind.REFLEX, arg=146))
    _run(mission, rover, 0.2, t0=t)
    ((x, y),) = mission.current_leg.stopped_by
    offset = mission.map.grid.config.sonar_offset_m
    assert x == pytest.approx(1.0 + offset + 0.146, abs=1e-6) and y == pytest.approx(0.8, abs=1e-6)  # east of it
