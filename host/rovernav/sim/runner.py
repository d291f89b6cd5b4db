"""One simulated mission, in lockstep: world, plant, sensors, camera, radio, firmware, host.

Every 10 ms of simulated time:
  1. the camera takes a frame when one is due (rendered from the true world, with noise and
     uneven light); the host's vision code locates the rover in it after the camera's latency,
     unless the frame is dropped: the simulator never hands the host the true pose;
  2. the host (the same Mission that `rovernav run` uses) reads the radio and acts;
  3. the rover's firmware core (through its C ABI) steps with the gyro sample, the last sonar
     result and the bytes the radio delivered, and its bytes go on the air at 57,600 baud;
  4. the plant moves under the motor commands; contacts and clearances are recorded.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..config import Config, config_from_dict
from ..cores import NativeCore, RoverCore
from ..link import messages_gen as mg
from ..link.link import Link
from ..mission import Detection, Mission, Outcome, leg_goal, leg_origin
from ..mission.spec import MissionSpec, start_host
from ..planning import NoPathError, OccupancyGrid, plan
from ..radio import ChannelConfig
from ..runlog.images import encode_jpeg
from ..vehicle_gen import STEP_PERIOD_MS
from ..vision import Locator
from . import camera_process
from .camera import Camera, Lighting, Renderer, RoverLook, Scene
from .channel import SimTransport, channel_pair, radio_figures
from .plant import PlantConfig, RoverPlant
from .setup import Setup
from .world import World

STEP_S = STEP_PERIOD_MS / 1000.0  # the rover's step (protocol/vehicle.toml)
HOST_PERIOD_S = 0.030
ROVER_CLOCK_SKEW = 0.005  # the rover's clock against the host's (half-duplex runs: when its bytes go on the air)
_NO_MARKERS: frozenset[str] = frozenset()
_ALL_MARKERS = frozenset({"front", "back", "tag"})  # a camera that sees no markers (--camera-outage-kind)
SIM_SIGN_CLOCK_START_S = mg.SIGN_EPOCH_UNIX_S + 86_400.0  # the simulated host's clock at t = 0 (Unix s)
HOST_BOOT_ID = 0x484F5354  # "HOST": the simulated host's boot id (+1 per restart)


@dataclasses.dataclass
class Faults:
    """What can go wrong on purpose (times in simulated seconds)."""

    link_outages: list[tuple[float, float]] = dataclasses.field(default_factory=list)  # (start, duration)
    camera_outages: list[tuple[float, float]] = dataclasses.field(default_factory=list)  # (start, duration)
    camera_outage_kind: str = "no_frames"  # or "no_markers"
    host_restarts: list[float] = dataclasses.field(default_factory=list)
    firmware_resets: list[float] = dataclasses.field(default_factory=list)
    gyro_dies_at: float | None = None


@dataclasses.dataclass
class SimOptions:
    seed: int = 1
    strategy: str = "rovernav"  # or "seed"
    camera_fps: float = 30.0
    camera_latency_s: float = 0.060
    frame_drop: float = 0.02
    max_time_s: float = 900.0
    host_replan: bool = True
    drive_mode: str | None = None  # "rotate_drive" or "pose_law" (the rover's DRIVE_MODE); None: the config's
    channel: ChannelConfig = ChannelConfig()
    plant: PlantConfig = PlantConfig()
    faults: Faults = dataclasses.field(default_factory=Faults)
    config: Config | None = None
    rover: str = "native"  # or "uno": build/uno/firmware.elf in simavr (cores/uno.py)
    signed: bool = True  # host and rover share a link key ([signing]); False: unsigned
    attacker: bool = False  # a second transmitter injects forged and replayed frames (attacker.py)
    log: Path | None = None  # the run's MCAP log (rovernav.runlog); None: none
    live_port: int | None = None  # serve the log's channels live on 127.0.0.1 at this port (0: any free one)
    log_image_hz: float = 2.0  # camera images kept in the log (and shown live) per second
    pace: float = 0.0  # > 0: run at this many times real time (for a live view); 0: flat out
    setup: Setup | None = None  # markers' colours, light, camera pose, plant (sim/setup.py); None: the usual
    # Render and locate frames in a second process, beside the loop (sim/camera_process.py): the
    # same frames and fixes, on a core to spare. Not with a frame_sink, which needs the frames.
    camera_process: bool = False


@dataclasses.dataclass
class Sample:
    """What the pictures and the report need at one instant."""

    t_s: float
    x_m: float
    y_m: float
    heading_deg: float
    est: tuple[float, float, float, float] | None  # x, y, heading, sd (m, m, deg, m) from the core's probe
    state: int
    trip: int


class Simulation:
    def __init__(
        self,
        scenario,
        options: SimOptions,
        frame_sink: Callable | None = None,
        progress: Callable[[float, str], None] | None = None,
    ):
        self.scenario = scenario
        self.opt = options
        self.cfg = options.config or config_from_dict(
            {"arena": {"width_m": scenario.arena.width_m, "height_m": scenario.arena.height_m}}
        )
        cfg_mode = self.cfg.rover.get(mg.Param.DRIVE_MODE)
        # What the rover is told, and what the report says: the flag, else the configuration.
        self.drive_mode = options.drive_mode or (
            mg.DriveMode(cfg_mode).name.lower() if cfg_mode is not None else "rotate_drive"
        )
        self.rng = np.random.default_rng(options.seed)
        self.world = World.from_scenario(scenario)
        s = scenario.start
        setup = options.setup
        self.plant = RoverPlant(
            s.x_m, s.y_m, s.heading_deg, setup.plant if setup is not None else options.plant, self.rng
        )
        if self.world.collides(self.plant.x, self.plant.y, self.plant.heading):
            from ..scenario import ScenarioError  # `rovernav plan` refuses such a start too

            raise ScenarioError(
                f"{scenario.path or scenario.name}: start ({s.x_m:g}, {s.y_m:g}) m, heading "
                f"{s.heading_deg:g} deg: the rover would stand on "
                f"{self.world.touching(self.plant.x, self.plant.y, self.plant.heading)}"
            )
        self.frame_sink = frame_sink
        self.progress = progress or (lambda t, text: None)
        # Both directions share one burst process and, half duplex, one medium (sim/channel.py).
        self.to_rover, self.to_host = channel_pair(options.channel, self.rng, self._outages())
        # The link key, as `rovernav keygen` would make it and `provision` store it (from its own
        # generator: the simulation's random draws stay those of an unsigned run), and the
        # counters the rover last stored (its EEPROM; the Uno image keeps its own in simavr).
        self.link_key = (
            bytes(np.random.default_rng([options.seed, 0x4B4559]).integers(0, 256, 16, dtype=np.uint8))
            if options.signed
            else None
        )
        self._stored_counters = (0, 0)
        self.attacker = None
        if options.attacker:
            from .attacker import Attacker

            self.attacker = Attacker(self.to_rover, seed=options.seed)
            self.to_rover.tap = self.attacker.observe
        self.core: RoverCore | None = None
        self.core = self._new_core(boot_id=int(self.rng.integers(1, 2**31)), reset_cause=1)
        look = RoverLook.for_vision(self.cfg.vision)
        lighting = Lighting.random(self.rng)
        w_m, h_m = scenario.arena.width_m, scenario.arena.height_m
        camera = Camera(lighting=lighting, noise_sigma=3.0)
        if setup is not None:
            look = dataclasses.replace(
                look, front_bgr=setup.front_bgr, back_bgr=setup.back_bgr, target_bgr=setup.target_bgr
            )
            camera = Camera(calibration=setup.mapping(w_m, h_m), lighting=setup.lighting or lighting, noise_sigma=3.0)
        renderer_args = (look, camera, int(self.rng.integers(2**31)))
        locator_args = (self.cfg.vision, scenario.arena.width_m, scenario.arena.height_m)
        self.renderer = Renderer(*renderer_args)
        self.locator = Locator(*locator_args)
        self._camera_proc: camera_process.CameraProcess | None = None
        if options.camera_process and frame_sink is None:
            self._camera_proc = camera_process.acquire(renderer_args, locator_args)
            # While the camera process starts (its imports, the arena's floor), load the compiled
            # planner here: the first plan would otherwise pay for it in the loop.
            from ..planning import warm_up

            warm_up()
        self.scene_base = Scene.of_scenario(
            scenario, self.cfg.vision.markers, setup.decoys(w_m, h_m) if setup is not None else ()
        )
        self.t = 0.0
        # The host's clock for its signing counter: simulated time from a fixed instant, so a run's
        # bytes are the same on every machine and every time (the rover, native or the Uno image,
        # starts each simulation with its counters at 0), and a restarted host's counters do not
        # depend on how fast this machine simulates.
        self._clock_epoch_s = SIM_SIGN_CLOCK_START_S
        self.samples: list[Sample] = []
        self.frames_rendered = 0
        self.frames_dropped = 0
        self.collisions = 0
        self.crash: dict | None = None  # where and when the rover first touched something
        self.timed_out = False
        self._in_contact = False
        self.min_clearance_m = math.inf
        self._pending_frames: collections.deque = collections.deque()
        self._next_frame_s = 0.0
        self._sonar_pending: int | None = None
        self._host_ticked = -1.0
        self.events: list[tuple[float, str]] = []
        self._map_dir = tempfile.TemporaryDirectory(prefix="rovernav-sim-")
        self.restarts_done = 0
        params = [(p, v) for p, v in self.cfg.rover_params() if p != mg.Param.DRIVE_MODE]
        if self.drive_mode != "rotate_drive" or mg.Param.DRIVE_MODE in self.cfg.rover:
            params.append((mg.Param.DRIVE_MODE, int(mg.DriveMode[self.drive_mode.upper()])))
        # The host's mission in plain values: the run log keeps it, and `rovernav replay` builds
        # the same mission from it. Its boot id says "HOST" (+1 per restart).
        self.spec = MissionSpec.for_run(
            scenario,
            self.cfg,
            strategy=options.strategy,
            host_replan=options.host_replan,
            rover_params=params,
            host_boot_id=HOST_BOOT_ID,
        )
        self.runlog = None
        if options.log is not None or options.live_port is not None:
            from ..runlog import RunLog

            self.runlog = RunLog(
                options.log,
                self.spec,
                source="sim",
                scenario=scenario,
                truth=True,
                live_port=options.live_port,
                image_hz=options.log_image_hz,
                meta={
                    "scenario": scenario.name,
                    "seed": options.seed,
                    "strategy": options.strategy,
                    "drive_mode": self.drive_mode,
                    "rover": options.rover,
                    "signed": options.signed,
                    "radio": options.channel.settings(),
                },
            )
            self.runlog.watch_radio(lambda: radio_figures(self.to_rover, self.to_host, self.runlog.t_s))
        self.mission = self._new_host()
        self._clairvoyant: OccupancyGrid | None = None

    # ---------------------------------------------------------------- set-up

    def _new_core(self, boot_id: int, reset_cause: int) -> RoverCore:
        """The rover's firmware: the core through its C ABI, or the Uno image in simavr, which
        pings the plant's sonar itself. A reset of the Uno keeps its EEPROM (boot counter)."""
        if self.opt.rover == "native":
            if self.core is not None:
                self.core.close()
            return NativeCore(
                boot_id=boot_id, reset_cause=reset_cause, key=self.link_key, counters=self._stored_counters
            )
        if self.opt.rover != "uno":
            raise ValueError(f"unknown rover {self.opt.rover!r}: native or uno")
        if self.core is not None:
            self.core.reset(reset_cause)
            return self.core
        from ..cores.uno import UnoCore

        return UnoCore(
            boot_id=boot_id,
            reset_cause=reset_cause,
            sonar=lambda: self.plant.sonar_mm(self.world),
            start_ms=int(round(getattr(self, "t", 0.0) * 1000)),
            key=self.link_key,
        )

    def uno_timing(self) -> dict | None:
        """The report's "uno_timing" (None for the native core), with where the worst step was."""
        if self.opt.rover != "uno":
            return None
        timing = self.core.timing()
        worst = timing.get("worst_step")
        if worst and self.samples:
            s = min(self.samples, key=lambda smp: abs(smp.t_s - worst["t_s"]))
            worst["x_m"], worst["y_m"] = round(s.x_m, 3), round(s.y_m, 3)
        return timing

    def _outages(self) -> list[tuple[float, float]]:
        return [(a, a + d) for a, d in self.opt.faults.link_outages]

    def _new_host(self) -> Mission:
        self.transport = SimTransport(self.to_rover, self.to_host)
        self.transport.set_time(self.t)
        transport = self.transport
        if self.runlog is not None:
            from ..runlog import RecordingTransport

            transport = RecordingTransport(self.transport, self.runlog)
        self.link = Link(transport, key=self.link_key, clock=lambda: self._clock_epoch_s + self.t)
        spec = self.spec.with_boot_id(HOST_BOOT_ID + self.restarts_done)
        if self.restarts_done and self.runlog is not None:
            self.runlog.new_host(self.t, spec.host_boot_id)
        return start_host(spec, self.link, Path(self._map_dir.name), on_event=self._event, recorder=self.runlog)

    def _event(self, t: float, text: str) -> None:
        """What the host says (the run log has it from the mission itself)."""
        self.events.append((t, text))
        self.progress(t, text)

    def _sim_event(self, t: float, text: str, level: str = "info") -> None:
        """What happens in the simulated world: faults, crashes, the time limit."""
        if self.runlog is not None:
            self.runlog.event(t, text, source="sim", level=level)
        self._event(t, text)

    # ---------------------------------------------------------------- the loop

    def run(self) -> None:
        ended_well = False
        try:
            self._run()
            ended_well = True
        finally:
            if self._camera_proc is not None:
                camera_process.release(self._camera_proc, ended_well)
                self._camera_proc = None

    def _run(self) -> None:
        f = self.opt.faults
        restarts = sorted(f.host_restarts)
        resets = sorted(f.firmware_resets)
        next_progress = 30.0
        wall0 = time.monotonic()
        while not self.mission.finished and self.crash is None:
            if self.t >= self.opt.max_time_s:
                self.timed_out = True
                self._sim_event(self.t, f"stopped by the time limit ({self.opt.max_time_s:g} s simulated)", "error")
                break
            now = self.t
            if self.opt.pace > 0:  # a live view: simulated time keeps pace with the wall clock
                time.sleep(max(0.0, wall0 + now / self.opt.pace - time.monotonic()))
            if self.runlog is not None:
                self.runlog.set_time(now)
                self._fault_edges(now)
            if restarts and now >= restarts[0]:
                restarts.pop(0)
                self._sim_event(
                    now,
                    "host restarted: the new host keeps what was on disk (the learned map, the legs "
                    "done) and takes the rest from the rover's HELLO and STATUS",
                    "warning",
                )
                # As a restarted process: nothing in memory survives, only the files the old host
                # kept in its working folder (start_host reloads them).
                self.restarts_done += 1
                self.mission = self._new_host()
            if resets and now >= resets[0]:
                resets.pop(0)
                self._sim_event(now, "firmware reset: the rover reboots with a new boot id", "warning")
                self.core = self._new_core(boot_id=int(self.rng.integers(1, 2**31)), reset_cause=4)
                self._sonar_pending = None
            if f.gyro_dies_at is not None and now >= f.gyro_dies_at and self.plant.gyro_alive:
                self.plant.gyro_alive = False
                self._sim_event(now, "the gyro stops answering", "warning")
            processed = self._camera(now)
            # The host's loop runs once a camera frame (the hardware runner's does too), and at
            # least every HOST_PERIOD_S when frames stop.
            if processed or now - self._host_ticked >= HOST_PERIOD_S:
                self._host_ticked = now
                self.transport.set_time(now)
                self.mission.tick(now)
            if self.attacker is not None:
                self.attacker.tick(now)
            self._rover(now)
            self.t = round(now + STEP_S, 6)
            if self.t >= next_progress:
                next_progress += 30.0
                self.progress(self.t, None)

    def _camera(self, now: float) -> bool:
        """Take a frame if one is due; hand the host the frames whose latency has passed.
        Returns whether the host got a frame."""
        if now + 1e-9 >= self._next_frame_s:
            self._next_frame_s += 1.0 / self.opt.camera_fps
            out = self._camera_out(now)
            if out == "no_frames":
                pass
            elif self.rng.random() < self.opt.frame_drop:
                self.frames_dropped += 1
            else:
                p = self.plant
                rover = (p.x, p.y, p.heading)
                hidden = _ALL_MARKERS if out == "no_markers" else _NO_MARKERS
                keep = self.runlog is not None and self.runlog.take_image(now)
                if self._camera_proc is not None:
                    # The same draw, the same frame, rendered and located in the camera process.
                    offsets = self.renderer.noise_offsets(self.rng)
                    self._camera_proc.submit(now, self.scene_base, rover, hidden, offsets, keep)
                    self.frames_rendered += 1
                    self._pending_frames.append((now, None, keep))
                else:
                    scene = dataclasses.replace(self.scene_base, rover=rover, hidden=hidden)
                    frame = self.renderer.render(scene, self.rng)
                    self.frames_rendered += 1
                    self._pending_frames.append((now, frame, keep))
                    if self.frame_sink is not None:
                        self.frame_sink(now, frame, self)
        processed = False
        while self._pending_frames and self._pending_frames[0][0] + self.opt.camera_latency_s <= now + 1e-9:
            processed = True
            self.transport.set_time(now)
            taken, frame, keep = self._pending_frames.popleft()
            # A kept frame goes in the log as it reaches the host (stamped when it was taken).
            if frame is not None:
                jpeg = encode_jpeg(frame) if keep else None
                det = self.locator.locate(frame, taken)
            else:
                det, jpeg = self._camera_proc.take()  # type: ignore[union-attr]
            if jpeg is not None:
                self.runlog.camera_jpeg(now, jpeg, taken_s=taken)  # type: ignore[union-attr]
            if det.rover is not None:
                x, y, h = det.rover
                self.mission.on_detection(Detection(taken, x, y, h), now)
            else:
                self.mission.on_detection(Detection(taken, None, None, None, det.reason), now)
        return processed

    def _fault_edges(self, now: float) -> None:
        """The run log's events for a radio or camera outage starting or ending at this step."""
        f = self.opt.faults
        for what, windows in (("radio", f.link_outages), (f"camera ({f.camera_outage_kind})", f.camera_outages)):
            for start, duration in windows:
                if start <= now < start + STEP_S:
                    self.runlog.event(now, f"{what} outage for {duration:g} s begins", source="sim", level="warning")
                elif start + duration <= now < start + duration + STEP_S:
                    self.runlog.event(now, f"{what} outage ends", source="sim", level="warning")

    def close_log(self, summary: dict | None = None) -> None:
        """End the run log (renamed into place; also for a run cut short)."""
        if self.runlog is not None:
            self.runlog.close(
                {
                    "outcome": self.outcome,
                    "host_outcome": self.mission.outcome.value,
                    "mission_time_s": self.t,
                    **(summary or {}),
                }
            )

    def _camera_out(self, now: float) -> str | None:
        for start, duration in self.opt.faults.camera_outages:
            if start <= now < start + duration:
                return self.opt.faults.camera_outage_kind
        return None

    def _rover(self, now: float) -> None:
        rx = self.to_rover.receive(now, 255)
        tx_room = max(0, mg.UART_BUFFER_BYTES - self.to_host.queued())  # the Uno's serial TX buffer
        out = self.core.step(
            int(round(now * 1000)),
            gyro_rate_mdps=self.plant.gyro_mdps(),
            sonar_range_mm=self._sonar_pending,
            rx=rx,
            tx_room=tx_room,
        )
        # (The Uno image pings the plant itself, through UnoCore's sonar callback.)
        self._sonar_pending = self.plant.sonar_mm(self.world) if out.fire_sonar and self.opt.rover == "native" else None
        if out.tx:
            at = now
            if self.opt.channel.half_duplex:
                # The rover's clock is not the host's: its 10 ms steps slide against the host's
                # loop (a ceramic resonator is off by up to 0.5 %), so on a shared medium the two
                # ends do not write in lock step, as they would on the simulator's common step.
                at = now + (now * ROVER_CLOCK_SKEW) % STEP_S
            self.to_host.write(out.tx, at)
        if self.opt.rover == "native":
            stored = self.core.take_persist()
            if stored is not None:
                self._stored_counters = stored
        self.plant.step(out.left_pwm, out.right_pwm, out.servo_cdeg, STEP_S)
        if self.runlog is not None:
            self.runlog.true_pose(now + STEP_S, self.plant.x, self.plant.y, self.plant.heading)
        # The exact footprint test only when a cheap lower bound says it could matter: a new
        # minimum clearance, or a contact.
        bound = self.world.clearance_bound_m(self.plant.x, self.plant.y)
        if bound <= 0.0 or bound < self.min_clearance_m:
            clearance = self.world.clearance_m(self.plant.x, self.plant.y, self.plant.heading)
            self.min_clearance_m = min(self.min_clearance_m, clearance)
        else:
            clearance = bound
        contact = clearance <= 0.0
        if contact and not self._in_contact:
            self.collisions += 1
            against = self.world.touching(self.plant.x, self.plant.y, self.plant.heading)
            # Motors cannot push a rover through a box or a wall: the run ends where it touched.
            self.crash = {
                "t_s": round(now, 2),
                "x_m": round(self.plant.x, 3),
                "y_m": round(self.plant.y, 3),
                "heading_deg": round(self.plant.heading, 1),
                "against": against,
            }
            self._sim_event(now, f"CRASH at ({self.plant.x:.2f}, {self.plant.y:.2f}) m against {against}")
            self.mission.fail(f"the rover crashed into {against}")
        self._in_contact = contact
        if int(round(now * 1000)) % 50 == 0:
            pr = self.core.probe()
            est = (
                (pr.x_mm / 1000, pr.y_mm / 1000, math.degrees(pr.heading_rad), pr.position_sd_mm / 1000)
                if pr.state != mg.RoverState.IDLE or pr.x_mm
                else None
            )
            self.samples.append(
                Sample(now, self.plant.x, self.plant.y, self.plant.heading, est, pr.state, len(self.mission.legs) - 1)
            )

    # ---------------------------------------------------------------- results

    @property
    def outcome(self) -> str:
        """How the run ended: reached, crashed, no_path (the host's verdict), failed, or timeout."""
        if self.crash is not None:
            return "crashed"
        if self.timed_out:
            return "timeout"
        return {
            Outcome.REACHED: "reached",
            Outcome.NO_PATH: "no_path",
            Outcome.FAILED: "failed",
            Outcome.RUNNING: "timeout",
        }[self.mission.outcome]

    def _clairvoyant_grid(self) -> OccupancyGrid:
        if self._clairvoyant is None:
            self._clairvoyant = OccupancyGrid.from_scenario(self.scenario, self.cfg.planner, all_obstacles=True)
        return self._clairvoyant

    def trip_optimal_m(self, index: int) -> float | None:
        """A* with every obstacle known for leg `index`: the best a clairvoyant rover does (None: no path)."""
        sc = self.scenario
        a, b = (sc.start.x_m, sc.start.y_m), (sc.target.x_m, sc.target.y_m)
        try:
            return plan(self._clairvoyant_grid(), leg_origin(a, b, index), leg_goal(a, b, index)).length_m
        except NoPathError:
            return None

    def optimal_length_m(self) -> float | None:
        """The clairvoyant optimum over every leg the mission asked (None: some leg has no path)."""
        lengths = [self.trip_optimal_m(i) for i in range(self.mission.legs_asked)]
        return None if any(v is None for v in lengths) else sum(lengths)
