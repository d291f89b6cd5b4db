"""`rovernav run`: a mission against a real rover and a real overhead camera.

The same Mission as in the simulator, fed by OpenCV's VideoCapture (a camera index or a video
file) and the rover's serial radio. The target and the known obstacles come from a scenario
file when one is given; otherwise the target is the yellow marker the camera sees and the map
starts empty, and the start is where the rover stands.
"""
from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from .config import load_config
from .errors import CameraError
from .link.errors import LinkError
from .link.link import Link
from .link.transport import SerialTransport, parse_serial_spec
from .mission import Detection, Mission, MissionFailed, Phase
from .planning import OccupancyGrid

log = logging.getLogger("rovernav.run")


def open_camera(source: str):
    import cv2

    src: int | str = int(source) if source.isdigit() else source
    if isinstance(src, str) and not Path(src).exists():
        raise CameraError(f"camera source {source!r}: no such file (give a camera index such as 0, or a video file)")
    cap = cv2.VideoCapture(src)
    if not cap.isOpened():
        raise CameraError(f"cannot open camera {source!r}: no such device or unreadable video")
    cap.set(cv2.CAP_PROP_FRAME_WIDTH, 640)
    cap.set(cv2.CAP_PROP_FRAME_HEIGHT, 480)
    return cap


def run_hardware(port: str, camera: str, config_path: str | None, scenario_path: str | None,
                 map_path: str | None = None, max_time_s: float = 1800.0) -> int:
    from .scenario import load_scenario
    from .vision import Locator

    cfg = load_config(config_path)
    port = port or cfg.link.port
    if not port:
        raise LinkError("no serial port: give --port or set [link] port in the configuration")
    scenario = load_scenario(scenario_path) if scenario_path else None
    arena_w, arena_h = (scenario.arena.width_m, scenario.arena.height_m) if scenario else \
        (cfg.arena.width_m, cfg.arena.height_m)
    locator = Locator(cfg.vision, arena_w, arena_h)
    cap = open_camera(camera or cfg.camera.source)
    name, baud = parse_serial_spec(port)
    transport = SerialTransport(name, baud if "@" in port else cfg.link.baud)
    link = Link(transport)

    # Where are we and where to? From the scenario, or from the first frames.
    first = None
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        ok, frame = cap.read()
        if not ok:
            raise CameraError(f"camera {camera!r} delivered no frame")
        first = locator.locate(frame, time.monotonic())
        if first.rover is not None and (scenario is not None or first.target is not None):
            break
    if first is None or first.rover is None:
        raise CameraError(f"the camera does not see the rover: {first.reason if first else 'no frame'}")
    if scenario is not None:
        grid = OccupancyGrid.from_scenario(scenario, cfg.planner)
        start, target = (scenario.start.x_m, scenario.start.y_m), (scenario.target.x_m, scenario.target.y_m)
        trips = cfg.mission.trips or scenario.mission.trips
        legs = trips * (2 if scenario.mission.kind == "out-and-back" else 1)
    else:
        if first.target is None:
            raise CameraError("no target marker in view and no --scenario to say where to go")
        grid = OccupancyGrid(arena_w, arena_h, cfg.planner)
        start, target = first.rover[:2], first.target
        legs = cfg.mission.trips or 1

    def say(t: float, text: str) -> None:
        print(f"[{t:7.2f} s] {text}", flush=True)

    mission = Mission(link, grid, start, target, legs=legs, rover_params=cfg.rover_params(),
                      fix_sd_mm=cfg.mission.fix_sd_mm, heartbeat_hz=cfg.mission.heartbeat_hz, on_event=say)
    map_file = map_path or cfg.mission.map
    if map_file and Path(map_file).exists():
        say(0.0, f"loaded {mission.load_map(map_file)} sonar echoes from {map_file}")
    t0 = time.monotonic()
    try:
        while not mission.done and time.monotonic() - t0 < max_time_s:
            ok, frame = cap.read()
            now = time.monotonic() - t0
            if ok:
                det = locator.locate(frame, now)
                if det.rover is not None:
                    mission.on_detection(Detection(now, *det.rover), now)
                else:
                    mission.on_detection(Detection(now, None, None, None, det.reason), now)
            mission.tick(now)
            if mission.phase is Phase.HELLO and now > 5.0:
                raise LinkError(f"no HELLO from the rover on {name}: is it powered, flashed, and on this port "
                                f"at {transport.baud if hasattr(transport, 'baud') else 57600} baud?")
    except KeyboardInterrupt:
        say(time.monotonic() - t0, "interrupted: stopping the rover")
    finally:
        from .link import messages_gen as mg

        try:
            link.send(mg.Stop(reason=mg.StopReason.OPERATOR))
        except LinkError:
            pass
        if map_file:
            mission.save_map(map_file)
        cap.release()
        transport.close()
    if mission.phase is Phase.FAILED:
        if mission.cause is not None:
            raise mission.cause   # the rover cannot be used (e.g. another protocol definition): exit 2
        raise MissionFailed(mission.error or "mission failed")
    done = sum(1 for t in mission.legs if t.reached)
    print(f"{done} of {mission.legs_asked} legs reached; {mission.replans} replans; "
          f"{len(mission.echoes)} sonar echoes folded into the map", file=sys.stderr)
    return 0 if mission.phase is Phase.DONE else 1
