"""`rovernav check`: a pre-flight check of the whole set-up, as an autopilot's pre-arm checks.

One short probe: HELLO and the parameters, the camera's frames, a sweep of the sonar with its
report range at the sensor's full range, 1 m (so that the floor, from 0.65 m, or a wall answers), then a drive
of 20 cm straight ahead (PROBE_AHEAD_M; stand the rover facing open floor), all watched by the
camera. From what the host saw it judges,
one line each, pass or fail with what to do:

    link     HELLO, the schema, signing, and the frames through both ways
    camera   frames, the rover and the target found in them
    gyro     no gyro fault reported (silent, implausible)
    sonar    echoes in the sweep (a ranger wired wrong answers nothing, anywhere)
    servo    the echoes differ across the sweep's bearings
    motors   the rover went ahead as told, seen by the camera (a motor wired backwards turns it
             round or drives it backwards)

A check that needs another that failed says "not checked" and why. The command ends with 0
when every check passed, 1 when one failed or could not be made.

In the simulator (`rovernav check --sim`) the same probe runs against the firmware core and the
simulated plant and camera, with a set-up (`--setup SEED`) and a fault (`--fault`) to find.
"""

from __future__ import annotations

import dataclasses
import math

from . import vehicle_gen as vehicle
from .link import messages_gen as mg
from .mission import Detection, Failure

#: How far ahead the probe drives [m], and how long the probe may take [s].
PROBE_AHEAD_M = 0.20
PROBE_TIME_S = 45.0
#: Frames through, each way, below which the link fails the check (missions are measured to hold
#: at 1 % byte loss: about 70 % of frames through; see the README's "A radio that loses bytes").
MIN_FRAMES_THROUGH = 0.6
#: Frames a direction must have carried before its loss is judged.
MIN_FRAMES_MEASURED = 40
#: Share of camera frames in which the rover must be found.
MIN_FOUND = 0.8
#: The parameters the probe sets: echoes reported out to the sensor's range, a sweep before it moves.
PROBE_PARAMS = [(mg.Param.SONAR_REPORT_MM, vehicle.SONAR_MAX_RANGE_MM), (mg.Param.SWEEP_AT_START, 1)]
FAULTS = ("dead-gyro", "sonar-unwired", "motor-reversed", "no-markers", "radio-loss-20")


@dataclasses.dataclass(frozen=True)
class CheckLine:
    name: str
    status: str  # "ok", "FAIL" or "not checked"
    text: str

    def __str__(self) -> str:
        return f"{self.name:<7}  {self.status:<11}  {self.text}"


class CameraWatch:
    """Counts the frames and what was found in them, then hands each detection on."""

    def __init__(self):
        self.frames = 0
        self.found = 0
        self.target_frames = 0
        self.poses: list[tuple[float, float, float, float]] = []  # t, x, y, heading
        self.reasons: dict[str, int] = {}
        self.first_s: float | None = None
        self.last_s = 0.0

    @property
    def span_s(self) -> float:
        """From the first frame to the last."""
        return self.last_s - self.first_s if self.first_s is not None else 0.0

    def saw(self, t_s: float, rover, target, reason: str | None) -> None:
        if self.first_s is None:
            self.first_s = t_s
        self.last_s = t_s
        self.frames += 1
        if target is not None:
            self.target_frames += 1
        if rover is not None:
            self.found += 1
            self.poses.append((t_s, *rover))
        elif reason:
            self.reasons[reason] = self.reasons.get(reason, 0) + 1


def judge(mission, watch: CameraWatch, elapsed_s: float, start_pose) -> list[CheckLine]:
    """The check's lines from a finished (or timed-out) probe mission."""
    lines: list[CheckLine] = []
    hello = mission.rover_boot_id is not None
    q = mission.quality.summary()
    # A direction is judged on MIN_FRAMES_MEASURED frames or more: over a probe cut short (a
    # rover that faults at once) the rover's last count lags the frames just sent.
    up, down = (
        q[d]["success"] if q[d]["frames_sent"] >= MIN_FRAMES_MEASURED else None
        for d in ("host_to_rover", "rover_to_host")
    )
    if mission.failure is Failure.SCHEMA:
        lines.append(CheckLine("link", "FAIL", f"{mission.error}: flash the firmware built from this protocol"))
    elif not hello and (mission.heard_any or mission.link.counters.dropped > 0):
        c = mission.link.counters
        lines.append(
            CheckLine(
                "link",
                "FAIL",
                f"the rover is on the air ({c.frames_ok} frames whole, {c.dropped} "
                f"broken, {mission.link.rx_bytes:,} bytes) but its HELLO did not get "
                f"through in {elapsed_s:.0f} s: the radio loses most frames (or the port "
                "is at another baud rate than the rover's); move the radios apart from "
                "Wi-Fi, closer, or to another channel (rovernav link-check --soak)",
            )
        )
    elif not hello:
        lines.append(
            CheckLine(
                "link",
                "FAIL",
                f"no HELLO from the rover in {elapsed_s:.0f} s: is it powered, flashed, "
                "on this port at the rover's baud rate, its radio paired?",
            )
        )
    elif (up is not None and up < MIN_FRAMES_THROUGH) or (down is not None and down < MIN_FRAMES_THROUGH):
        lines.append(
            CheckLine(
                "link",
                "FAIL",
                f"frames through {_pct(up)} to the rover, {_pct(down)} from it: missions "
                f"need {100 * MIN_FRAMES_THROUGH:.0f} % or more; move the radios apart "
                "from Wi-Fi, closer, or to another channel (rovernav link-check --soak)",
            )
        )
    else:
        lines.append(
            CheckLine(
                "link",
                "ok",
                f"HELLO, schema 0x{mg.SCHEMA_HASH:08x}, "
                f"{'signed' if mission.link.signer is not None else 'unsigned'}; frames "
                f"through {_pct(up)} to the rover, {_pct(down)} from it",
            )
        )
    # A gyro fault shows as the rover's FAULT event, its STATUS's fault code, or START refused
    # as FAULTED (its detail the code): whichever the radio let through.
    code = mission.last_status.fault if mission.last_status is not None else 0
    gyro_fault = (
        (mission.failure is Failure.ROVER_FAULT and "gyro" in (mission.error or ""))
        or code in (mg.FaultCode.GYRO_SILENT, mg.FaultCode.GYRO_IMPLAUSIBLE)
        or "refused start: faulted" in (mission.error or "")
    )
    rover_seen = watch.found >= MIN_FOUND * watch.frames
    camera_ok = watch.frames > 0 and rover_seen and watch.target_frames > 0
    if not rover_seen:
        why = max(watch.reasons, key=watch.reasons.get) if watch.reasons else "no rover marker"
        lines.append(
            CheckLine(
                "camera",
                "FAIL",
                f"the rover found in {watch.found} of {watch.frames} frames ({why}): "
                "calibrate the camera (rovernav calibrate camera) or uncover the "
                "rover's markers",
            )
        )
    elif not camera_ok:
        lines.append(
            CheckLine(
                "camera",
                "FAIL",
                f"the target marker found in none of {watch.frames} frames: put it in "
                "view, or calibrate the camera (rovernav calibrate camera)",
            )
        )
    else:
        rate = watch.frames / max(watch.span_s, 1e-9)
        lines.append(
            CheckLine(
                "camera",
                "ok",
                f"{rate:.0f} frames/s; the rover in {watch.found} of {watch.frames}, "
                f"the target in {watch.target_frames}",
            )
        )
    # The probe ended before its sweep or its drive for a reason of its own (a deadline, no path):
    # the checks that needed them say so instead of blaming the sonar or the motors.
    ended = (
        mission.failure is not None
        and mission.failure is not Failure.ROVER_FAULT
        and mission.failure is not Failure.SCHEMA
        and not gyro_fault
    )
    link_failed = lines[0].status == "FAIL"
    if not hello:
        lines.append(CheckLine("gyro", "not checked", "no link"))
    elif gyro_fault:
        what = (
            mg.FaultCode(code).name.lower()
            if code in mg.FaultCode._value2member_map_ and code
            else (mission.error or "a gyro fault").removeprefix("rover fault: ")
        )
        lines.append(
            CheckLine(
                "gyro",
                "FAIL",
                f"{what}: check the MPU6050's wiring (SDA A4, SCL A5, 3.3 V, GND) "
                "and that it is an MPU6050 at address 0x68",
            )
        )
    elif mission.last_status is None:
        lines.append(CheckLine("gyro", "not checked", "no STATUS from the rover"))
    else:
        lines.append(CheckLine("gyro", "ok", "answering, no fault reported"))
    readings = mission.map.readings
    echoes = [r for r in readings if r.range_m is not None]
    if not readings:
        blocked = (
            "no link"
            if not hello
            else "the rover stops on a gyro fault"
            if gyro_fault
            else "the camera does not see the rover, so no sweep was asked"
            if not camera_ok
            else f"the probe ended: {mission.error}"
            if ended
            else "the link fails"
            if link_failed
            else "the rover did not sweep"
        )
        lines.append(CheckLine("sonar", "not checked", blocked))
        lines.append(CheckLine("servo", "not checked", blocked))
    elif not echoes:
        lines.append(
            CheckLine(
                "sonar",
                "FAIL",
                f"no echo in {len(readings)} pings out to {vehicle.SONAR_MAX_RANGE_MM / 1000:g} m, where the floor answers "
                "from 0.65 m: check the HC-SR04's wiring (TRIG A1, ECHO A0, 5 V, GND)",
            )
        )
        lines.append(CheckLine("servo", "not checked", "no echoes to compare across bearings"))
    else:
        ranges = [r.range_m for r in echoes]
        lines.append(
            CheckLine(
                "sonar",
                "ok",
                f"{len(echoes)} echoes in {len(readings)} pings, {min(ranges):.2f} to {max(ranges):.2f} m",
            )
        )
        bearings = {round(r.bearing_deg) for r in echoes}
        if len(bearings) < 3:
            lines.append(
                CheckLine(
                    "servo",
                    "FAIL",
                    f"echoes at {len(bearings)} bearing(s) only: is the servo turning (pin 9, its 5 V)?",
                )
            )
        elif max(ranges) - min(ranges) < 0.02 and len(echoes) >= 5:
            lines.append(
                CheckLine(
                    "servo",
                    "FAIL",
                    "the same range at every bearing: the servo does not turn the ranger (pin 9, its 5 V)",
                )
            )
        else:
            lines.append(
                CheckLine(
                    "servo",
                    "ok",
                    f"echoes at {len(bearings)} bearings, "
                    f"{min(r.bearing_deg for r in echoes):.0f} to "
                    f"{max(r.bearing_deg for r in echoes):.0f} degrees",
                )
            )
    lines.append(_motors(mission, watch, start_pose, hello, camera_ok, gyro_fault, ended, link_failed))
    return lines


def _motors(
    mission,
    watch: CameraWatch,
    start_pose,
    hello: bool,
    camera_ok: bool,
    gyro_fault: bool,
    ended: bool,
    link_failed: bool,
) -> CheckLine:
    if not hello:
        return CheckLine("motors", "not checked", "no link")
    if not camera_ok or start_pose is None:
        return CheckLine("motors", "not checked", "the camera does not see the rover")
    if gyro_fault:
        return CheckLine("motors", "not checked", "the rover stops on a gyro fault")
    if link_failed:
        return CheckLine("motors", "not checked", "the link fails")
    x0, y0, h0 = start_pose
    after = watch.poses
    _, x1, y1, _ = after[-1]
    fwd = math.radians(h0)
    ahead = (x1 - x0) * math.sin(fwd) + (y1 - y0) * math.cos(fwd)
    moved = math.hypot(x1 - x0, y1 - y0)
    turned = max(abs((p[3] - h0 + 180.0) % 360.0 - 180.0) for p in after)
    if mission.phase.name == "DONE" and ahead > 0.5 * PROBE_AHEAD_M:
        return CheckLine(
            "motors", "ok", f"went {100 * ahead:.0f} cm ahead as told, turning {turned:.0f} degrees at most"
        )
    if ended and moved < 0.03:
        return CheckLine("motors", "not checked", f"the probe ended before it drove: {mission.error}")
    if moved < 0.03 and turned < 20:
        return CheckLine(
            "motors",
            "FAIL",
            "the rover did not move: the motor driver's power, its enable pins, the motors' wires (pins 3, 5, 6, 11)",
        )
    if ahead < -0.03 or (turned >= 45 and abs(ahead) < 0.5 * PROBE_AHEAD_M):
        went = f"went {100 * -ahead:.0f} cm backwards" if ahead < 0 else f"went {100 * ahead:.0f} cm ahead"
        return CheckLine(
            "motors",
            "FAIL",
            f"told to drive {100 * PROBE_AHEAD_M:.0f} cm straight ahead, the rover {went} "
            f"turning {turned:.0f} degrees: a motor turns the wrong way (swap its two "
            "wires)",
        )
    return CheckLine(
        "motors",
        "FAIL",
        f"the rover went {100 * ahead:.0f} cm ahead of the {100 * PROBE_AHEAD_M:.0f} cm "
        f"asked, turning {turned:.0f} degrees: calibrate the rover's motors",
    )


def _pct(v: float | None) -> str:
    return "not measured (too few frames)" if v is None else f"{100 * v:.0f} %"


# ---------------------------------------------------------------- in the simulator


def sim_options_for(fault: str | None, setup, seed: int, config):
    """SimOptions for a probe with one fault injected (FAULTS) in a set-up (None: the usual)."""
    from .radio import ChannelConfig
    from .sim.plant import PlantConfig
    from .sim.runner import Faults, SimOptions

    faults, channel = Faults(), ChannelConfig()
    plant = setup.plant if setup is not None else PlantConfig()
    if fault == "dead-gyro":
        faults = Faults(gyro_dies_at=0.0)
    elif fault == "no-markers":
        faults = Faults(camera_outages=[(0.0, 10 * PROBE_TIME_S)], camera_outage_kind="no_markers")
    elif fault == "radio-loss-20":
        channel = ChannelConfig(byte_loss=0.20)
    elif fault == "sonar-unwired":
        plant = dataclasses.replace(plant, sonar_connected=False)
    elif fault == "motor-reversed":
        plant = dataclasses.replace(plant, left_motor_reversed=True)
    elif fault is not None:
        raise ValueError(f"unknown fault {fault!r} (known: {', '.join(FAULTS)})")
    if setup is not None:
        setup = dataclasses.replace(setup, plant=plant)
        return SimOptions(
            seed=seed, max_time_s=PROBE_TIME_S, faults=faults, channel=channel, setup=setup, config=config
        )
    return SimOptions(seed=seed, max_time_s=PROBE_TIME_S, faults=faults, channel=channel, plant=plant, config=config)


def probe_scenario(arena_w_m: float, arena_h_m: float):
    """An empty arena with the rover left of its middle, facing +x, and the target PROBE_AHEAD_M
    straight ahead of it."""
    from .scenario import Arena, Mission, Pose, Scenario, Target

    x, y, h = arena_w_m / 2 - PROBE_AHEAD_M / 2, arena_h_m / 2, 90.0
    tx, ty = x + PROBE_AHEAD_M * math.sin(math.radians(h)), y + PROBE_AHEAD_M * math.cos(math.radians(h))
    return Scenario(
        name="check",
        arena=Arena(arena_w_m, arena_h_m),
        start=Pose(x, y, h),
        target=Target(tx, ty),
        mission=Mission("reach", 1),
        obstacles=(),
        description="rovernav check's probe",
    )


def check_sim(config, fault: str | None = None, setup_seed: int | None = None, seed: int = 1):
    """The check against the simulated rover: (lines, elapsed_s)."""
    from .sim.runner import Simulation
    from .sim.setup import Setup

    setup = Setup.random(setup_seed) if setup_seed is not None else None
    scenario = probe_scenario(config.arena.width_m, config.arena.height_m)
    cfg = dataclasses.replace(config, rover={**config.rover, **dict(PROBE_PARAMS)})
    sim = Simulation(scenario, sim_options_for(fault, setup, seed, cfg))
    watch = CameraWatch()
    original = sim.mission.on_detection

    def on_detection(d: Detection, now: float) -> None:
        target = getattr(sim, "_last_target", None)
        watch.saw(d.t_s, None if d.x_m is None else (d.x_m, d.y_m, d.heading_deg), target, d.reason)
        original(d, now)

    sim.mission.on_detection = on_detection
    locate = sim.locator.locate

    def locate_and_keep_target(frame, t=None):
        det = locate(frame, t)
        sim._last_target = det.target
        return det

    sim.locator.locate = locate_and_keep_target
    sim.run()
    start_pose = next(((x, y, h) for _, x, y, h in watch.poses), None)  # the camera's first fix
    return judge(sim.mission, watch, sim.t, start_pose), sim.t


def passed(lines: list[CheckLine]) -> bool:
    """Every line ok: a check not made is not a pass."""
    return all(ln.status == "ok" for ln in lines)


def summary_line(lines: list[CheckLine]) -> str:
    failed = [ln.name for ln in lines if ln.status == "FAIL"]
    unchecked = [ln.name for ln in lines if ln.status == "not checked"]
    if not failed and not unchecked:
        return f"every check passed ({len(lines)})"
    parts = []
    if failed:
        parts.append(f"{len(failed)} check{'s' if len(failed) > 1 else ''} failed: {', '.join(failed)}")
    if unchecked:
        parts.append(f"{len(unchecked)} not made: {', '.join(unchecked)}")
    return "; ".join(parts)


# ---------------------------------------------------------------- on the real rover


def check_hardware(port: str, camera: str | None, config_path: str | None) -> tuple[list[CheckLine], float]:
    """The check against the real rover on `port`, watched by `camera`: (lines, elapsed_s). Every
    input is checked before a device is opened (InputError, exit 2)."""
    import os
    import time

    from .config import load_config
    from .errors import CameraError
    from .hardware import _plain_file, _serial_port, camera_source, link_key, open_camera
    from .link.link import Link
    from .link.transport import SerialTransport
    from .mission.spec import MissionSpec
    from .vision import Locator

    _plain_file(config_path, "configuration file")
    cfg = load_config(config_path)
    name, baud = _serial_port(port, cfg, config_path)
    source = camera_source(camera or cfg.camera.source)
    w, h = cfg.arena.width_m, cfg.arena.height_m
    locator = Locator(cfg.vision, w, h)
    key = link_key(cfg, config_path)
    cap = open_camera(source)
    transport = None
    watch = CameraWatch()
    try:
        transport = SerialTransport(name, baud)
        first = None
        t0 = time.monotonic()
        while time.monotonic() - t0 < 5.0:
            ok, frame = cap.read()
            if not ok:
                raise CameraError(f"camera {str(source)!r} delivered no frame")
            first = locator.locate(frame, time.monotonic() - t0)
            watch.saw(time.monotonic() - t0, first.rover, first.target, first.reason)
            if first.rover is not None:
                break
        start_pose = None if first is None or first.rover is None else tuple(first.rover)
        if start_pose is not None:
            x, y, hd = start_pose
            tx, ty = x + PROBE_AHEAD_M * math.sin(math.radians(hd)), y + PROBE_AHEAD_M * math.cos(math.radians(hd))
            room = cfg.planner.inflation_m + 0.02  # the planner keeps this from the arena's wall
            if not (room <= tx <= w - room and room <= ty <= h - room):
                raise CameraError(
                    f"the rover at ({x:.2f}, {y:.2f}) m faces the arena's wall: turn it to face open "
                    f"floor, {100 * PROBE_AHEAD_M + 20:.0f} cm clear ahead, for the motor check"
                )
        else:
            # Not seen: the link and the camera are still checked, and the rover is not driven (its
            # goal is where it is said to stand, so a leg done at once).
            x, y = w / 2, h / 2
            tx, ty = x, y
        probe_cfg = dataclasses.replace(cfg, rover={**cfg.rover, **dict(PROBE_PARAMS)})
        spec = MissionSpec.for_run(
            None, probe_cfg, start_xy=(x, y), target_xy=(tx, ty), host_boot_id=int.from_bytes(os.urandom(4), "little")
        )
        link = Link(transport, key=key)
        mission = spec.build(link, on_event=lambda t, text: None)
        t0 = time.monotonic()
        try:
            while not mission.finished and time.monotonic() - t0 < PROBE_TIME_S:
                ok, frame = cap.read()
                now = time.monotonic() - t0
                if ok:
                    det = locator.locate(frame, now)
                    watch.saw(now, det.rover, det.target, det.reason)
                    if start_pose is not None:  # a rover not seen at the start is never sent anywhere
                        mission.on_detection(
                            Detection(now, *det.rover)
                            if det.rover is not None
                            else Detection(now, None, None, None, det.reason),
                            now,
                        )
                mission.tick(now)
        finally:
            # Stop, and give back the parameters the probe changed (the rover keeps a CONFIG until
            # it restarts, and the next mission sends only what its configuration names).
            restore = [mg.Stop(reason=mg.StopReason.OPERATOR)] + [
                mg.Config(param=int(p), value=int(cfg.rover.get(p, mg.PARAMS[p].default))) for p, _ in PROBE_PARAMS
            ]
            for message in restore:
                try:
                    link.request(message, timeout_s=0.5, retries=3)
                except Exception:  # noqa: BLE001 - the port may be gone; the lines say what was seen
                    pass
        return judge(mission, watch, time.monotonic() - t0, start_pose), time.monotonic() - t0
    finally:
        cap.release()
        if transport is not None:
            transport.close()
