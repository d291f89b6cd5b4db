"""`rovernav run`: a mission against a real rover and a real overhead camera.

The same Mission as in the simulator, fed by OpenCV's VideoCapture (a camera index or a video
file) and the rover's serial radio. The target and the known obstacles come from a scenario
file when one is given; otherwise the target is the yellow marker the camera sees and the map
starts empty, and the start is where the rover stands.

Every input (the configuration, the scenario, the port spec, the camera source, the learned
map to load and the place to save it) is read and checked before the camera or the port is
opened, so a bad one ends the command with a one-line error naming the file and key (exit 2)
and touches no device. Ctrl-C stops the rover, saves the map (atomically: the file on disk is
the old map or the new one, never half of either) and exits with status 130.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import stat
import sys
import time
from pathlib import Path

from .config import load_config
from .errors import CameraError, InputError, MapFileError
from .link.errors import LinkError, PortSpecError
from .link.link import Link
from .link.transport import SerialTransport, parse_serial_spec
from .mapping.learned_map import check_map_path, read_map_file
from .mission import Detection, Mission, MissionFailed, Phase
from .planning import OccupancyGrid
from .validate import MAX_SIM_TIME_S, check_number

log = logging.getLogger("rovernav.run")

#: Highest camera index accepted (OpenCV numbers devices from 0).
MAX_CAMERA_INDEX = 999
#: `rovernav run` prints the mission's status line (phase, rover, frames through both ways) this often [s].
STATUS_LINE_S = 5.0


def camera_source(source: object) -> int | str:
    """A camera index or an existing video file, or InputError naming the value (nothing is opened)."""
    text = source if isinstance(source, str) else ""
    if not text.strip():
        raise InputError("no camera: give --camera (an index such as 0, or a video file) or set [camera] source")
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise InputError(f"camera source {text!r}: control characters in it")
    stripped = text.strip()
    if stripped.isascii() and stripped.isdigit():
        if len(stripped.lstrip("0")) > 3 or int(stripped) > MAX_CAMERA_INDEX:  # a few digits: int() is cheap
            shown = f"{text[:12]!r}{'...' if len(text) > 12 else ''}"
            raise InputError(
                f"camera index {shown} is past {MAX_CAMERA_INDEX}: give a camera index such as 0, or a video file"
            )
        return int(stripped)
    path = Path(text)
    if not path.exists():
        raise InputError(f"camera source {text!r}: no such file (give a camera index such as 0, or a video file)")
    if path.is_dir():
        raise InputError(f"camera source {text!r}: is a folder (give a camera index such as 0, or a video file)")
    return text


def open_camera(source: str | int):
    import cv2

    src = camera_source(source) if isinstance(source, str) else source
    try:  # OpenCV's own warnings about a missing device would add lines to our one-line error
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    except AttributeError:
        pass
    cap = cv2.VideoCapture(src)
    if not cap.isOpened():
        raise CameraError(f"cannot open camera {str(source)!r}: no such device or unreadable video")
    cap.set(cv2.CAP_PROP_FRAME_WIDTH, 640)
    cap.set(cv2.CAP_PROP_FRAME_HEIGHT, 480)
    return cap


#: Largest configuration or scenario file read (a TOML file of a few kilobytes in practice).
MAX_TOML_BYTES = 1024 * 1024


def _plain_file(path: str | None, what: str) -> None:
    """InputError for a path that names a device, a pipe or a huge file, which reading whole
    would hang on or fill memory with (/dev/zero, a FIFO). A missing path is left to its loader
    (a scenario may be given by name)."""
    if not path:
        return
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a folder, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{path}: not a regular file (a device or a pipe), not a {what}")
    if st.st_size > MAX_TOML_BYTES:
        raise InputError(f"{path}: {st.st_size:,} bytes; a {what} is at most {MAX_TOML_BYTES:,}")


def _serial_port(port: str, cfg, config_path: str | None) -> tuple[str, int]:
    """(device, baud) from --port or the configuration's [link] port; PortSpecError naming where it came from."""
    spec = port or cfg.link.port
    if not isinstance(spec, str) or not spec.strip():
        raise PortSpecError("no serial port: give --port or set [link] port in the configuration")
    try:
        name, baud = parse_serial_spec(spec)
    except PortSpecError as exc:
        if port:
            raise PortSpecError(f"--port: {exc}") from None
        raise PortSpecError(f"{config_path}: [link] port: {exc}") from None
    return name, (baud if "@" in spec else cfg.link.baud)


def link_key(cfg, config_path: str | None) -> bytes | None:
    """The link key the configuration names ([link] key_file; a relative path is the config
    file's neighbour), or None for an unsigned link. `rovernav run` and `rovernav check` share it."""
    if not cfg.link.key_file:
        return None
    from .link.keys import load_key_file

    key_path = Path(cfg.link.key_file)
    if not key_path.is_absolute() and config_path:
        key_path = Path(config_path).parent / key_path
    return load_key_file(key_path)


def read_frame(cap, t0: float, runlog=None):
    """The camera's next frame: (ok, frame, now), now in seconds since t0 (time.monotonic()); the run
    log (a RunLog, or a fleet's FleetRunLog) told the time and given the frame."""
    ok, frame = cap.read()
    now = time.monotonic() - t0
    if runlog is not None:
        runlog.set_time(now)
        if ok:
            runlog.camera_image(now, frame)
    return ok, frame, now


def default_log_path() -> Path:
    """run-YYYYMMDD-HHMMSS.mcap in the current folder (-2, -3, ... after it when a run of the same
    second has that name already: no run's log is written over another's)."""
    from .runlog.channels import partial_path

    stem = time.strftime("run-%Y%m%d-%H%M%S")
    for k in range(1, 1000):
        path = Path(f"{stem}.mcap" if k == 1 else f"{stem}-{k}.mcap")
        if not path.exists() and not partial_path(path).exists():
            return path
    raise InputError(f"{stem}-*.mcap: a thousand run logs of this second already; give --log")


def run_hardware(
    port: str,
    camera: str,
    config_path: str | None,
    scenario_path: str | None,
    map_path: str | None = None,
    max_time_s: float = 1800.0,
    log_path: str | Path | None = None,
    live_port: int | None = None,
    log_image_hz: float = 2.0,
) -> int:
    """A mission on the real rover. `log_path`: the run log (MCAP; None: none); `live_port`:
    serve it live on 127.0.0.1 (rovernav.runlog)."""
    from .mission.spec import MissionSpec
    from .runlog import RecordingTransport, RunLog
    from .scenario import load_scenario
    from .vision import Locator

    # ---- 1. every input, before any device is opened
    max_time_s = check_number("max_time_s", max_time_s, 0.0, MAX_SIM_TIME_S, lo_open=True)
    _plain_file(config_path, "configuration file")
    _plain_file(scenario_path, "scenario file")
    cfg = load_config(config_path)
    name, baud = _serial_port(port, cfg, config_path)
    source = camera_source(camera or cfg.camera.source)
    scenario = load_scenario(scenario_path) if scenario_path else None
    arena_w, arena_h = (
        (scenario.arena.width_m, scenario.arena.height_m) if scenario else (cfg.arena.width_m, cfg.arena.height_m)
    )
    grid = (
        OccupancyGrid.from_scenario(scenario, cfg.planner)
        if scenario is not None
        else OccupancyGrid(arena_w, arena_h, cfg.planner)
    )
    map_file = map_path or cfg.mission.map or None
    readings = None
    if map_file:
        check_map_path(map_file)
        if Path(map_file).exists():
            readings = read_map_file(map_file, grid)
    locator = Locator(cfg.vision, arena_w, arena_h)
    key = link_key(cfg, config_path)

    def say(t: float, text: str) -> None:
        print(f"[{t:7.2f} s] {text}", flush=True)

    # ---- 2. the devices
    cap = open_camera(source)
    transport = link = runlog = None
    mission: Mission | None = None
    interrupted = False
    try:
        transport = SerialTransport(name, baud)

        # Where are we and where to? From the scenario, or from the first frames.
        first = None
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            ok, frame = cap.read()
            if not ok:
                raise CameraError(f"camera {str(source)!r} delivered no frame")
            first = locator.locate(frame, time.monotonic())
            if first.rover is not None and (scenario is not None or first.target is not None):
                break
        if first is None or first.rover is None:
            raise CameraError(f"the camera does not see the rover: {first.reason if first else 'no frame'}")
        if scenario is None and first.target is None:
            raise CameraError("no target marker in view and no --scenario to say where to go")
        spec = MissionSpec.for_run(
            scenario,
            cfg,
            start_xy=None if scenario else first.rover[:2],
            target_xy=None if scenario else first.target,
            host_boot_id=int.from_bytes(os.urandom(4), "little"),
        )
        if log_path is not None or live_port is not None:
            meta = {"port": name, "camera": str(source), "scenario": scenario.name if scenario else ""}
            if readings is not None:
                meta["initial_map"] = [dataclasses.asdict(r) for r in readings]
            runlog = RunLog(
                log_path,
                spec,
                source="hardware",
                scenario=scenario,
                live_port=live_port,
                image_hz=log_image_hz,
                meta=meta,
            )
            if runlog.live_port is not None:
                say(0.0, f"live view: open Foxglove and connect to ws://localhost:{runlog.live_port}")
        link = Link(transport if runlog is None else RecordingTransport(transport, runlog), key=key)
        mission = spec.build(link, on_event=say, recorder=runlog)
        if readings is not None:
            say(0.0, f"loaded {mission.map.replay(readings)} sonar readings from {map_file}")
        t0 = time.monotonic()
        next_status_s = STATUS_LINE_S
        try:
            while not mission.finished and time.monotonic() - t0 < max_time_s:
                ok, frame, now = read_frame(cap, t0, runlog)
                if ok:
                    det = locator.locate(frame, now)
                    if det.rover is not None:
                        mission.on_detection(Detection(now, *det.rover), now)
                    else:
                        mission.on_detection(Detection(now, None, None, None, det.reason), now)
                mission.tick(now)
                if now >= next_status_s:  # the status line: where the mission is, and the radio both ways
                    next_status_s = now + STATUS_LINE_S
                    say(now, mission.status_line())
                if mission.phase is Phase.HELLO and now > 5.0:
                    raise LinkError(
                        f"no HELLO from the rover on {name}: is it powered, flashed, and on this port at {baud} baud?"
                    )
        except KeyboardInterrupt:
            interrupted = True
            say(time.monotonic() - t0, "interrupted: stopping the rover")
    finally:
        ending_with = sys.exc_info()[1]  # an error already on its way out is the one to report
        try:
            if link is not None:
                from .link import messages_gen as mg

                try:
                    link.send(mg.Stop(reason=mg.StopReason.OPERATOR))
                except LinkError:
                    pass
        finally:
            try:
                if mission is not None and map_file:
                    _save_map(mission, map_file, quiet=ending_with is not None)
            finally:
                cap.release()
                if transport is not None:
                    transport.close()
                if runlog is not None:
                    runlog.close(
                        {
                            "host_outcome": mission.outcome.value if mission else "not started",
                            "interrupted": interrupted or ending_with is not None,
                        }
                    )
                    if log_path is not None:
                        print(f"run log: {log_path} (`rovernav replay {log_path}`)", file=sys.stderr)
    if interrupted:
        _summary(mission)
        raise KeyboardInterrupt
    if mission.phase is Phase.FAILED:
        if mission.cause is not None:
            raise mission.cause  # the rover cannot be used (e.g. another protocol definition): exit 2
        raise MissionFailed(mission.error or "mission failed", mission.failure)
    _summary(mission)
    return 0 if mission.phase is Phase.DONE else 1


def _save_map(mission: Mission, map_file: str, quiet: bool) -> None:
    """Save the learned map (atomically: the old file stays whole if this fails or is interrupted).
    A failure is a one-line MapFileError; when the run is already ending with another error
    (quiet), that one is kept and this one only printed."""
    try:
        mission.save_map(map_file)
    except OSError as exc:
        error = MapFileError(f"{map_file}: could not save the learned map: {exc.strerror or exc}")
        if quiet:
            print(f"rovernav run: {error}", file=sys.stderr)
            return
        raise error from None


def _summary(mission: Mission) -> None:
    done = sum(1 for t in mission.legs if t.reached)
    print(
        f"{done} of {mission.legs_asked} legs reached; {mission.replans} replans; "
        f"{len(mission.echoes)} sonar echoes folded into the map",
        file=sys.stderr,
    )
