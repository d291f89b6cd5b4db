"""Driving the runs: where they go, whether the rover stands where they can go, and the runs
themselves, against the simulated rover (runs_sim) or the real one (runs_hardware).
"""

from __future__ import annotations

import dataclasses
import math

from ...angles import wrap_deg
from ...link import messages_gen as mg
from .runs import STILL_S, WALL_FACING_DEG, CalibrationFailed, Run, wall_geometry

#: Drive commands of the runs [PWM], the length of each run [m].
LEVELS_PWM = (60, 80, 105)
RUN_M = 0.5
#: The sonar's wall: the rover's centre this far from it in the simulator's bench [m]; on the real
#: rover the sensor must be WALL_RANGE_M from it (and the rover face it within WALL_FACING_DEG).
SIM_WALL_M = 0.40
WALL_RANGE_M = (0.15, 0.5)
#: What the runs set: sweeps off (a sweep stops the rover), rotate-and-drive, and the level.
RUN_PARAMS = [
    (mg.Param.SWEEP_INTERVAL_MM, 0),
    (mg.Param.SWEEP_AT_START, 0),
    (mg.Param.SWEEP_BEFORE_TURN_DEG, 0),
    (mg.Param.DRIVE_MODE, int(mg.DriveMode.ROTATE_DRIVE)),
]


def plan_runs(
    start_xy: tuple[float, float], heading_deg: float, levels=LEVELS_PWM, run_m: float = RUN_M
) -> list[tuple[int, tuple[float, float], tuple[float, float]]]:
    """(level, start, goal) for each run: ahead from where the rover stands, then back, and so on."""
    h = math.radians(heading_deg)
    a = start_xy
    b = (a[0] + run_m * math.sin(h), a[1] + run_m * math.cos(h))
    out = []
    for i, level in enumerate(levels):
        out.append((level, a, b) if i % 2 == 0 else (level, b, a))
    return out


def check_room(
    start_xy, heading_deg: float, arena_w_m: float, arena_h_m: float, margin_m: float, run_m: float = RUN_M
) -> None:
    """CalibrationFailed unless the runs' line lies margin_m inside the arena."""
    (_, a, b) = plan_runs(start_xy, heading_deg, (0,), run_m)[0]
    for x, y in (a, b):
        if not (margin_m <= x <= arena_w_m - margin_m and margin_m <= y <= arena_h_m - margin_m):
            raise CalibrationFailed(
                f"the runs go from ({a[0]:.2f}, {a[1]:.2f}) to ({b[0]:.2f}, {b[1]:.2f}) m, closer "
                f"than {margin_m:.2f} m to the arena's edge: turn the rover to face "
                f"{run_m + margin_m:.1f} m of open floor"
            )


def check_wall(
    wall: tuple[float, float, float, float], x_m: float, y_m: float, heading_deg: float, sonar_offset_m: float
) -> None:
    """CalibrationFailed unless the rover at (x_m, y_m), heading_deg stands in front of the wall's
    face, facing it within WALL_FACING_DEG, its sensor WALL_RANGE_M from it (by the offset the
    configuration says: the measure is the offset's correction)."""
    geo = wall_geometry(wall, x_m, y_m)
    if isinstance(geo, str):
        raise CalibrationFailed(f"--wall: {geo}: stand the rover facing the wall, in front of it")
    d_m, normal_deg = geo
    off = abs(wrap_deg(heading_deg - normal_deg))
    if off > WALL_FACING_DEG:
        raise CalibrationFailed(
            f"--wall: the rover faces {off:.0f} degrees off square to the wall (within "
            f"{WALL_FACING_DEG:.0f}, please: turn it to face the wall)"
        )
    sensor_m = d_m - sonar_offset_m * math.cos(math.radians(off))
    lo, hi = WALL_RANGE_M
    if not lo <= sensor_m <= hi:
        raise CalibrationFailed(
            f"--wall: the ranger is {sensor_m:.2f} m from the wall (the camera's place for the "
            f"rover): stand it {lo:.2f}-{hi:.2f} m from the wall"
        )


def run_error(mission, finished: bool) -> str | None:
    """Why a run's mission ended short, in words (None: it reached its goal): a fault the rover
    reports by name first (rovernav check says what to do about it)."""
    code = mission.last_status.fault if mission.last_status is not None else 0
    if code:
        name = mg.FaultCode(code).name.lower() if code in mg.FaultCode._value2member_map_ else f"code {code}"
        return f"the rover reports a fault, {name} (rovernav check names what to fix)"
    if not finished:
        return "the run took longer than it may"
    return None if mission.error is None else f"the run ended: {mission.error}"


def _watch(mission, run: Run, clock) -> None:
    """Notes in `run` what the mission hears and sends: each STATUS (and the run's extra status
    hooks), each echo of a sweep, and when START is first sent; and START waits for the run's
    still window."""
    send, on_status, on_obstacle = mission._send, mission._on_status, mission._on_obstacle

    def sending(message, again: bool = False):
        if isinstance(message, mg.Start) and run.start_sent_s is None:
            run.start_sent_s = clock()
        return send(message, again)

    def status(m):
        run.status.append((clock(), int(m.state), int(m.left_pwm), int(m.right_pwm), int(m.heading_cdeg)))
        if run.fixed_at_s is None and not m.flags & mg.StatusFlag.DEAD_RECKONING:
            run.fixed_at_s = clock()
        for hook in run.on_status_hooks:
            hook(m)
        on_status(m)

    def obstacle(m):
        if m.range_mm:
            run.echoes.append((clock(), m.bearing_cdeg / 100.0, m.range_mm / 1000.0))
        on_obstacle(m)

    mission._send, mission._on_status, mission._on_obstacle = sending, status, obstacle
    mission.hold_start = run.hold_start


# ---------------------------------------------------------------- in the simulator


def sim_bench(config) -> tuple[tuple[float, float], float, tuple[float, float, float, float]]:
    """The simulator's bench: where the rover stands (its centre) and faces, and the wall's face
    (x0, y0, x1, y1) SIM_WALL_M ahead of it, square to it, 0.6 m long: the runs go the other way
    from the arena's middle."""
    w, h = config.arena.width_m, config.arena.height_m
    start = (w / 2 + RUN_M / 2, h / 2)
    face_x = start[0] + SIM_WALL_M
    return start, 90.0, (face_x, h / 2 - 0.3, face_x, h / 2 + 0.3)


def runs_sim(config, setup=None, seed: int = 1, levels=LEVELS_PWM, progress=None) -> list[Run]:
    """The runs against the simulated rover (a set-up's plant, or the usual one), each its own
    simulation of the same rover, as on the real one: the rover stands on the bench (sim_bench)
    facing the wall, still for STILL_S, sweeps, turns round and runs away from the wall; then back,
    from where the last run left it facing (so it turns round first); and so on. In the sim, a
    run's status rows also note the plant's true gyro bias (Run.true_bias), for the tests."""
    from ...scenario import Arena, Mission, Pose, Scenario, Target, Wall
    from ...sim.runner import SimOptions, Simulation

    w, h = config.arena.width_m, config.arena.height_m
    start, facing, face = sim_bench(config)
    thick = 0.02
    wall = Wall(face[0] + thick / 2, face[1], face[2] + thick / 2, face[3], thick)
    runs = []
    plan = plan_runs(start, facing + 180.0, levels)
    for i, (level, a, b) in enumerate(plan):
        heading = facing if i == 0 else math.degrees(math.atan2(a[0] - plan[i - 1][1][0], a[1] - plan[i - 1][1][1]))
        scenario = Scenario(
            name="calibrate-rover",
            arena=Arena(w, h),
            start=Pose(a[0], a[1], heading % 360.0),
            target=Target(*b),
            mission=Mission("reach", 1),
            obstacles=(),
            walls=(wall,),
            description="rovernav calibrate rover's run",
        )
        # The runs that begin on the bench (the first and third) begin with a sweep of the wall.
        swept = i % 2 == 0
        extra = [(mg.Param.SWEEP_AT_START, 1)] if swept else []
        cfg = dataclasses.replace(config, rover={**config.rover, **dict(RUN_PARAMS + extra), mg.Param.DRIVE_PWM: level})
        run = Run(level, a, b, turn_first=True, swept=swept, still_s=STILL_S if i == 0 else 0.0)
        sim = Simulation(scenario, SimOptions(seed=seed + i, max_time_s=run.time_limit_s, config=cfg, setup=setup))
        _watch(sim.mission, run, lambda sim=sim: sim.t)
        on_detection = sim.mission.on_detection

        def saw(d, now, run=run, on_detection=on_detection):
            if d.x_m is not None:
                run.poses.append((d.t_s, d.x_m, d.y_m, d.heading_deg))
            if not run.withhold(now):
                on_detection(d, now)

        def truth(m, run=run, sim=sim):
            run.true_bias.append((sim.t, sim.plant.gyro_bias))

        sim.mission.on_detection = saw
        run.on_status_hooks.append(truth)
        sim.run()
        run.error = run_error(sim.mission, sim.outcome != "timeout")
        runs.append(run)
        if progress is not None:
            progress(i + 1, len(levels))
    return runs


# ---------------------------------------------------------------- on the real rover


def runs_hardware(
    port: str,
    camera: str | None,
    config_path: str | None,
    levels=LEVELS_PWM,
    progress=None,
    wall: tuple[float, float, float, float] | None = None,
) -> list[Run]:
    """The runs on the real rover on `port`, watched by `camera`, one mission a run on one link;
    from where the camera first sees the rover, ahead the way it faces, then back (with `wall`,
    the face of a wall it stands facing: a sweep first, and the runs away from the wall). Every input is
    checked before a device is opened (InputError, exit 2); the parameters the runs change are
    given back, and the rover stopped, at the end."""
    import os
    import time

    from ...config import load_config
    from ...errors import CameraError, InputError
    from ...hardware import _plain_file, _serial_port, camera_source, link_key, open_camera
    from ...link.link import Link
    from ...link.transport import SerialTransport
    from ...mission import Detection
    from ...mission.spec import MissionSpec
    from ...vision import Locator

    _plain_file(config_path, "configuration file")
    cfg = load_config(config_path)
    name, baud = _serial_port(port, cfg, config_path)
    source = camera_source(camera or cfg.camera.source)
    locator = Locator(cfg.vision, cfg.arena.width_m, cfg.arena.height_m)
    key = link_key(cfg, config_path)
    cap = open_camera(source)
    transport = link = None
    runs: list[Run] = []
    try:
        transport = SerialTransport(name, baud)
        link = Link(transport, key=key)
        t0 = time.monotonic()
        first = None
        while time.monotonic() - t0 < 5.0 and first is None:
            ok, frame = cap.read()
            if not ok:
                raise CameraError(f"camera {str(source)!r} delivered no frame")
            first = locator.locate(frame, time.monotonic() - t0).rover
        if first is None:
            raise CameraError("the camera did not find the rover in 5 s: run rovernav calibrate camera first")
        x, y, heading = first
        try:
            if wall is not None:
                check_wall(wall, x, y, heading, cfg.planner.sonar_offset_m)
                heading = (heading + 180.0) % 360.0  # the runs go away from the wall
            check_room((x, y), heading, cfg.arena.width_m, cfg.arena.height_m, cfg.planner.inflation_m + 0.02)
        except CalibrationFailed as exc:
            raise InputError(str(exc)) from None
        for i, (level, a, b) in enumerate(plan_runs((x, y), heading, levels)):
            # With a wall, the runs that begin where the rover stood (the first and third) begin
            # with a sweep of it.
            swept = wall is not None and i % 2 == 0
            run = Run(
                level, a, b, turn_first=i > 0 or wall is not None, swept=swept, still_s=STILL_S if i == 0 else 0.0
            )
            extra = [(mg.Param.SWEEP_AT_START, 1)] if swept else []
            params = {**cfg.rover, **dict(RUN_PARAMS + extra), mg.Param.DRIVE_PWM: level}
            spec = MissionSpec.for_run(
                None,
                dataclasses.replace(cfg, rover=params),
                start_xy=a,
                target_xy=b,
                host_boot_id=int.from_bytes(os.urandom(4), "little"),
            )
            mission = spec.build(link, on_event=lambda t, text: None)
            _watch(mission, run, lambda: time.monotonic() - t0)
            started = time.monotonic()
            while not mission.finished and time.monotonic() - started < run.time_limit_s:
                ok, frame = cap.read()
                now = time.monotonic() - t0
                if ok:
                    det = locator.locate(frame, now)
                    if det.rover is not None:
                        run.poses.append((now, *det.rover))
                        if not run.withhold(now):
                            mission.on_detection(Detection(now, *det.rover), now)
                    else:
                        mission.on_detection(Detection(now, None, None, None, det.reason), now)
                mission.tick(now)
            run.error = run_error(mission, mission.finished)
            runs.append(run)
            if progress is not None:
                progress(i + 1, len(levels))
    finally:
        if link is not None:
            restore = [mg.Stop(reason=mg.StopReason.OPERATOR)] + [
                mg.Config(param=int(p), value=int(cfg.rover.get(p, mg.PARAMS[p].default)))
                for p, _ in RUN_PARAMS + [(mg.Param.DRIVE_PWM, 0)]
            ]
            for message in restore:
                try:
                    link.request(message, timeout_s=0.5, retries=3)
                except Exception:  # noqa: BLE001 - the port may be gone; the runs say what was seen
                    pass
        cap.release()
        if transport is not None:
            transport.close()
    return runs
