"""`rovernav run --rovers N`: a fleet's shuttle with real rovers, one overhead camera, one radio.

The same FleetHost as the simulator's (`rovernav sim SCENARIO --rovers N`): rover k (provisioned
with `rovernav provision --fleet-id K`, its own key) shuttles between the scenario's k-th start
and k-th site, the camera finds each by its own ArUco tag (vision/fleet.py's fleet_tags: with
the defaults rover 1 tag 1, rover 2 tag 3, rover 3 tag 4, rover 4 tag 5), and the host gives each
rover its slots on the one half-duplex radio.

As `rovernav run` does for one rover, every input is read and checked before the camera or the
port is opened (a one-line error, exit 2); Ctrl-C stops every rover and exits with status 130.
The run log has a channel set per rover (runlog/fleet.py).
"""

from __future__ import annotations

import dataclasses
import os
import sys
import tempfile
import time
from pathlib import Path

from ..errors import InputError
from ..link.errors import LinkError
from ..link.messages_gen import MAX_ROVERS
from ..mission import Outcome, Phase
from ..mission.legs import round_trips_done

#: A rover's own configuration may put its sonar this far from where the fleet's says [m]: the
#: host places every rover's echoes with the fleet's one offset, and the planner's sonar margin
#: (0.05 m by default) holds a few millimetres of it.
SONAR_OFFSET_SLACK_M = 0.005


def fleet_keys(key_files: list[str] | None, rovers: int, config_key_file: str) -> list[bytes | None]:
    """Each rover's link key, from --key-files (one a rover, in order), or None for each (unsigned);
    InputError when the count is wrong, or when the configuration names one key ([link] key_file):
    a fleet's rovers have a key each."""
    from ..link.keys import load_key_file

    if not key_files:
        if config_key_file:
            raise InputError(
                f"[link] key_file names one key; a fleet's rovers each have their own: give --key-files "
                f"with {rovers} files, rover 1's first"
            )
        return [None] * rovers
    if len(key_files) != rovers:
        raise InputError(f"--key-files: {len(key_files)} files for {rovers} rovers (one a rover, rover 1's first)")
    return [load_key_file(Path(f)) for f in key_files]


def fleet_rover_params(config_files: list[str] | None, rovers: int, fleet_cfg=None) -> tuple[dict, ...] | None:
    """Each rover's own parameters from --rover-configs (one configuration file a rover, rover 1's first,
    as `rovernav calibrate rover --write FILE` writes it for that rover): its [rover] table, sent to
    that rover over the fleet configuration's (`fleet_cfg`, None: the defaults): rovers of a fleet
    are not alike, each has its own motors. Only [rover] is taken from them; the camera, the planner
    and the rest are the fleet configuration's, and so are the parameters of a rover's share of the
    air (FLEET_ROVER_PARAMS) and the planner's geometry. None without the flag. InputError (one
    line) when the count is wrong, when a file's [rover] sets one of those, or when it says the
    rover's sonar sits more than SONAR_OFFSET_SLACK_M from where the fleet's configuration says (the
    host places every rover's echoes with that one offset); ConfigError for a file that is not a
    valid configuration, or whose moving-to-a-pose gains are unstable over the fleet's."""
    from ..config import check_pose_gains, config_from_dict, read_config_data
    from ..link import messages_gen as mg
    from .host import FLEET_ROVER_PARAMS

    if not config_files:
        return None
    if len(config_files) != rovers:
        raise InputError(
            f"--rover-configs: {len(config_files)} files for {rovers} rovers (one a rover, rover 1's first)"
        )
    fleet_cfg = fleet_cfg if fleet_cfg is not None else config_from_dict({})
    out = []
    for f in config_files:
        data = read_config_data(f)  # read once: the checked configuration, and what the file itself says
        cfg = config_from_dict(data, where=f"{Path(f)}: ")  # (as load_config names it)
        own = dict(cfg.rover)
        for p, _ in FLEET_ROVER_PARAMS:
            if p in own:
                raise InputError(
                    f"{f}: [rover] {mg.PARAMS[p].name} is the fleet's to set (each rover's share of the air), "
                    "not one rover's: leave it out"
                )
        for p, _ in fleet_cfg.planner.rover_geometry():
            if p in own:
                raise InputError(
                    f"{f}: [rover] {mg.PARAMS[p].name} is the planner's geometry, the fleet's to set ([planner] of "
                    "its configuration), not one rover's: leave it out"
                )
        check_pose_gains({**fleet_cfg.rover, **own}, f"{f} over the fleet's configuration: ")
        said = data.get("planner", {})
        offset, fleet_offset = cfg.planner.sonar_offset_m, fleet_cfg.planner.sonar_offset_m
        if "sonar_offset_m" in said and abs(offset - fleet_offset) > SONAR_OFFSET_SLACK_M:
            raise InputError(
                f"{f}: [planner] sonar_offset_m = {offset:g} m, the fleet's configuration {fleet_offset:g} m: the host "
                "places every rover's echoes with one offset; mount the rovers' rangers alike, or set the fleet's to theirs"
            )
        out.append(own)
    return tuple(out)


def run_fleet_hardware(
    rovers: int,
    port: str,
    camera: str,
    config_path: str | None,
    scenario_path: str | None,
    key_files: list[str] | None = None,
    max_time_s: float = 1800.0,
    rover_configs: list[str] | None = None,
    log_path: str | Path | None = None,
    log_image_hz: float = 2.0,
    trips: int | None = None,
) -> int:
    from .. import hardware  # its devices (tests stand in for them there), its checks of inputs
    from ..config import load_config
    from ..hardware import _plain_file, _serial_port, camera_source
    from ..scenario import load_scenario
    from ..validate import MAX_SIM_TIME_S, check_number
    from ..vision.fleet import FleetLocator, fleet_tags
    from .host import FleetHost, fleet_specs
    from .radio import FleetRadio

    # ---- 1. every input, before any device is opened
    if not 2 <= rovers <= MAX_ROVERS:
        raise InputError(f"--rovers {rovers}: a fleet has 2 to {MAX_ROVERS} rovers (one rover: leave --rovers out)")
    max_time_s = check_number("max_time_s", max_time_s, 0.0, MAX_SIM_TIME_S, lo_open=True)
    if not scenario_path:
        raise InputError(
            "--rovers needs --scenario: its [[starts]] are the rovers' berths and its [[sites]] their sites"
        )
    _plain_file(config_path, "configuration file")
    _plain_file(scenario_path, "scenario file")
    cfg = load_config(config_path)
    cfg = dataclasses.replace(cfg, vision=dataclasses.replace(cfg.vision, markers="aruco"))
    if trips is not None:
        cfg = dataclasses.replace(cfg, mission=dataclasses.replace(cfg.mission, trips=trips))
    name, baud = _serial_port(port, cfg, config_path)
    source = camera_source(camera or cfg.camera.source)
    scenario = load_scenario(scenario_path)
    boot = int.from_bytes(os.urandom(4), "little") & 0x0FFFFFFF
    own = fleet_rover_params(rover_configs, rovers, cfg)
    specs = fleet_specs(scenario, cfg, rovers, boot, own=own)  # ScenarioError: too few starts
    keys = fleet_keys(key_files, rovers, cfg.link.key_file)
    aruco = cfg.vision.aruco
    tags = fleet_tags(rovers, aruco.rover_id, aruco.target_id)
    locator = FleetLocator(cfg.vision, scenario.arena.width_m, scenario.arena.height_m, tags)

    def say(k: int, t: float, text: str) -> None:
        print(f"[{t:7.2f} s]{'' if k < 0 else f' rover {k + 1}:'} {text}", flush=True)

    say(-1, 0.0, "the rovers' tags: " + ", ".join(f"rover {k} tag {t}" for k, t in tags.items()))
    # ---- 2. the devices
    cap = hardware.open_camera(source)
    transport = host = runlog = None
    interrupted = False
    workdir = tempfile.TemporaryDirectory(prefix="rovernav-fleet-")
    try:
        transport = hardware.SerialTransport(name, baud)
        if log_path is not None:
            from ..runlog.fleet import FleetRunLog

            runlog = FleetRunLog(
                log_path,
                specs,
                source="hardware",
                scenario=scenario,
                image_hz=log_image_hz,
                meta={"port": name, "camera": str(source), "scenario": scenario.name},
            )
        radio = FleetRadio(transport, rovers)
        host = FleetHost(
            specs,
            radio,
            keys,
            workdir.name,
            on_event=say,
            recorders=None if runlog is None else runlog.rovers,
        )
        t0 = time.monotonic()
        try:
            while not host.finished and time.monotonic() - t0 < max_time_s:
                ok, frame, now = hardware.read_frame(cap, t0, runlog)
                if ok:
                    host.on_seen(locator.locate(frame, now), now, now)
                host.tick(now)
                host.air(now)  # a slot when the air is free: once a frame (a slot is 60-100 ms long)
                unheard = [k + 1 for k, m in enumerate(host.missions) if m.phase is Phase.HELLO]
                if unheard and now > 10.0:
                    raise LinkError(
                        f"no HELLO from rover(s) {', '.join(map(str, unheard))} on {name}: powered, flashed, "
                        f"provisioned with --fleet-id, and on this radio at {baud} baud?"
                    )
        except KeyboardInterrupt:
            interrupted = True
            say(-1, time.monotonic() - t0, "interrupted: stopping the rovers")
    finally:
        ending_with = sys.exc_info()[1]
        try:
            if host is not None:
                from ..link import messages_gen as mg

                for link in host.links:
                    try:
                        link.send(mg.Stop(reason=mg.StopReason.OPERATOR))
                    except LinkError:
                        pass
        finally:
            cap.release()
            if transport is not None:
                transport.close()
            if runlog is not None:
                runlog.close(
                    {
                        "host_outcome": [m.outcome.value for m in host.missions] if host else "not started",
                        "interrupted": interrupted or ending_with is not None,
                    }
                )
                print(f"run log: {log_path} (a channel set per rover: /rover1/..., /rover2/...)", file=sys.stderr)
            workdir.cleanup()
    if interrupted:
        raise KeyboardInterrupt
    for k, m in enumerate(host.missions):
        done = round_trips_done(m.legs)
        print(f"rover {k + 1}: {m.outcome.value}, {done} of {m.legs_asked // 2} round trips", file=sys.stderr)
    if any(m.phase is Phase.FAILED for m in host.missions):
        return 1
    # (A rover that gave up its trips ends home, its mission done but failed.)
    return 0 if all(m.phase is Phase.DONE and m.outcome is Outcome.REACHED for m in host.missions) else 1
