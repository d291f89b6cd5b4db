"""A fleet's mission in the simulator (issue 30): N rovers under one camera, on one radio.

Every 10 ms of simulated time, as `runner.Simulation` does for one rover:
  1. the camera takes a frame when one is due, drawing every rover with its own ArUco tag; after
     the camera's latency the host's FleetLocator finds each rover in it (or says why not);
  2. the host's FleetHost acts once a frame (every mission, the traffic rules, the shared map),
     and gives a rover its slot on the radio whenever the air is free;
  3. each rover's firmware core steps with its gyro, its last sonar result and the bytes the
     radio gave it; its bytes go on the one half-duplex air, where they collide with anyone's
     sent at the same time (sim/channel.py's fleet_channels);
  4. each plant moves; a contact with an obstacle, a wall or another rover ends the run.

Each rover's sonar sees the other rovers' bodies as well as the arena's shapes.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import tempfile
import time
from collections.abc import Callable

import numpy as np

from ..config import Config, config_from_dict
from ..cores import NativeCore
from ..fleet.host import FleetHost, fleet_specs
from ..fleet.radio import FleetRadio, grant_air_s
from ..link import messages_gen as mg
from ..link.transport import Transport
from ..mapping.sonar_map import sonar_origin
from ..mission import Outcome
from ..mission.legs import round_trips_done
from ..radio import ChannelConfig
from ..vehicle_gen import STEP_PERIOD_MS
from ..vision.fleet import FleetLocator, fleet_tags
from .camera import Camera, Lighting, Renderer, RoverLook, Scene
from .channel import Broadcast, Channel, fleet_channels
from .plant import PlantConfig, RoverPlant
from .runner import HOST_BOOT_ID, HOST_PERIOD_S, ROVER_CLOCK_SKEW, SIM_SIGN_CLOCK_START_S
from .world import World, _corners

STEP_S = STEP_PERIOD_MS / 1000.0
#: No leg of any rover done for this long, and no rover driven MOVED_M in the last STILL_S: the fleet
#: is stuck (a deadlock) [s]. Rovers still on the move (slowly: a lossy radio, waiting in turn) are
#: given up to SLOW_S with no leg done.
STUCK_S = 150.0
STILL_S = 60.0
MOVED_M = 0.2
SLOW_S = 450.0


@dataclasses.dataclass
class FleetOptions:
    rovers: int = 3
    seed: int = 1
    camera_fps: float = 30.0
    camera_latency_s: float = 0.060
    frame_drop: float = 0.02
    max_time_s: float = 1800.0
    trips: int | None = None  # None: the scenario's
    channel: ChannelConfig = ChannelConfig(half_duplex=True)
    plant: PlantConfig = PlantConfig()
    #: Each rover's own plant (rover 1's first), for a fleet of rovers unlike each other; None: all
    #: are `plant`. Fewer than the rovers: the rest are `plant`.
    plants: tuple[PlantConfig, ...] | None = None
    #: Each rover's own parameters (rover 1's first: Param to raw value, its motors' calibration,
    #: say) over the configuration's; None: every rover the configuration's.
    rover_params: tuple[dict, ...] | None = None
    config: Config | None = None
    signed: bool = True
    rover1: str = "native"  # or "uno": rover 1 is the Uno image in simavr (cores/uno.py)
    log: object | None = None  # the run's MCAP log, a channel set per rover (runlog/fleet.py); None: none
    log_image_hz: float | None = None  # camera images in the log a second (None: the log's default)
    #: The host's seen-ground trial (fleet/host.py; off: the fleet as measured in docs/results.md).
    seen_ground_trial: bool = False
    #: The host's turn-care trial (fleet/host.py; off: the fleet as measured in docs/results.md).
    turn_care_trial: bool = False


class FleetSimTransport(Transport):
    """The host's end of the fleet's radio: writes go to every rover at once; reads are what
    the rovers' transmitters delivered, rover after rover."""

    def __init__(self, broadcast: Broadcast, from_rovers: list[Channel]):
        super().__init__("sim-fleet-radio")
        self.broadcast = broadcast
        self.from_rovers = from_rovers
        self.now_s = 0.0

    def _write(self, data: bytes) -> None:
        self.broadcast.write(data, self.now_s)

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        return b"".join(c.receive(self.now_s, max_bytes) for c in self.from_rovers)

    def _close(self) -> None:
        pass


def rectangles_touch(a: list, b: list) -> bool:
    """Whether two convex polygons (corner lists) overlap (separating axes)."""
    for poly in (a, b):
        for i in range(len(poly)):
            x0, y0 = poly[i]
            x1, y1 = poly[(i + 1) % len(poly)]
            nx, ny = y0 - y1, x1 - x0
            pa = [nx * x + ny * y for x, y in a]
            pb = [nx * x + ny * y for x, y in b]
            if max(pa) < min(pb) or max(pb) < min(pa):
                return False
    return True


def ray_polygon_m(x: float, y: float, direction_deg: float, poly: list, max_m: float) -> float:
    """How far a ray from (x, y) along direction_deg (0 = +y, clockwise) runs before it meets the
    polygon's edge (max_m if it does not)."""
    d = math.radians(direction_deg)
    dx, dy = math.sin(d), math.cos(d)
    best = max_m
    for i in range(len(poly)):
        ax, ay = poly[i]
        bx, by = poly[(i + 1) % len(poly)]
        ex, ey = bx - ax, by - ay
        den = dx * ey - dy * ex
        if abs(den) < 1e-12:
            continue
        t = ((ax - x) * ey - (ay - y) * ex) / den
        u = ((ax - x) * dy - (ay - y) * dx) / den
        if 0.0 <= u <= 1.0 and 0.0 <= t < best:
            best = t
    return best


@dataclasses.dataclass
class RoverSim:
    """One rover of the simulated fleet: its plant, its firmware, its radio ends, its figures."""

    index: int
    plant: RoverPlant
    core: object
    to_rover: Channel
    to_host: Channel
    sonar_pending: int | None = None
    anchor: tuple[float, float] = (0.0, 0.0)  # where it stood when it last moved MOVED_M
    distance_m: float = 0.0
    crash: dict | None = None
    #: Simulated seconds by what the rover was doing (`FleetSimulation.doing`): where a fleet's
    #: time goes, against the same rover alone.
    time_s: collections.Counter = dataclasses.field(default_factory=collections.Counter)


class FleetSimulation:
    def __init__(
        self,
        scenario,
        options: FleetOptions,
        progress: Callable[[float, str | None], None] | None = None,
    ):
        self.scenario = scenario
        self.opt = options
        n = options.rovers
        scenario.fleet_legs(n)  # ScenarioError (one line) for too few starts
        if scenario.mission.kind != "out-and-back":  # a shuttle goes out and back, whatever the file asked
            from ..scenario import Mission as ScenarioMission

            scenario = dataclasses.replace(scenario, mission=ScenarioMission("out-and-back", scenario.mission.trips))
            self.scenario = scenario
        base = options.config or config_from_dict(
            {"arena": {"width_m": scenario.arena.width_m, "height_m": scenario.arena.height_m}}
        )
        vision = dataclasses.replace(base.vision, markers="aruco")
        self.cfg = dataclasses.replace(base, vision=vision)
        self.rng = np.random.default_rng(options.seed)
        self.world = World.from_scenario(scenario)
        self.progress = progress or (lambda t, text: None)
        self.events: list[tuple[float, int, str]] = []
        broadcast, to_rovers, to_hosts = fleet_channels(options.channel, self.rng, n)
        self.host_transport = FleetSimTransport(broadcast, to_hosts)
        self.rovers: list[RoverSim] = []
        self.keys: list[bytes | None] = []
        for k in range(n):
            s = scenario.starts[k]
            own = options.plants[k] if options.plants and k < len(options.plants) else options.plant
            plant = RoverPlant(s.x_m, s.y_m, s.heading_deg, own, self.rng)
            key = (
                bytes(np.random.default_rng([options.seed, 0x4B4559, k]).integers(0, 256, 16, dtype=np.uint8))
                if options.signed
                else None
            )
            self.keys.append(key)
            boot_id = int(self.rng.integers(1, 2**31))
            r = RoverSim(k, plant, None, to_rovers[k], to_hosts[k])
            if k == 0 and options.rover1 == "uno":
                from ..cores.uno import UnoCore

                r.core = UnoCore(
                    boot_id=boot_id, reset_cause=1, sonar=lambda r=r: self._sonar_mm(r), key=key, fleet_id=1
                )
            elif options.rover1 not in ("native", "uno"):
                raise ValueError(f"unknown rover {options.rover1!r}: native or uno")
            else:
                r.core = NativeCore(boot_id=boot_id, reset_cause=1, key=key, fleet_id=k + 1)
            self.rovers.append(r)
        for r in self.rovers:
            if self.world.collides(r.plant.x, r.plant.y, r.plant.heading):
                from ..scenario import ScenarioError

                raise ScenarioError(
                    f"{scenario.path or scenario.name}: rover {r.index + 1}'s start "
                    f"({r.plant.x:g}, {r.plant.y:g}) m stands on "
                    f"{self.world.touching(r.plant.x, r.plant.y, r.plant.heading)}"
                )
        trips = options.trips
        cfg = self.cfg
        if trips is not None:
            cfg = dataclasses.replace(cfg, mission=dataclasses.replace(cfg.mission, trips=trips))
        self.specs = fleet_specs(scenario, cfg, n, HOST_BOOT_ID, own=options.rover_params)
        self.t = 0.0
        self.radio = FleetRadio(self.host_transport, n)
        self._workdir = tempfile.TemporaryDirectory(prefix="rovernav-fleet-")
        self.runlog = None
        if options.log is not None:
            from ..runlog.fleet import FleetRunLog

            extra = {} if options.log_image_hz is None else {"image_hz": options.log_image_hz}
            self.runlog = FleetRunLog(
                options.log,
                self.specs,
                source="sim",
                scenario=scenario,
                truth=True,
                meta={
                    "scenario": scenario.name,
                    "seed": options.seed,
                    "rover": options.rover1,
                    "signed": options.signed,
                    "radio": options.channel.settings(),
                },
                **extra,
            )
        self.host = FleetHost(
            self.specs,
            self.radio,
            self.keys,
            self._workdir.name,
            clock=lambda: SIM_SIGN_CLOCK_START_S + self.t,
            on_event=self._host_event,
            recorders=None if self.runlog is None else self.runlog.rovers,
            seen_ground_trial=options.seen_ground_trial,
            turn_care_trial=options.turn_care_trial,
        )
        look = RoverLook.for_vision(self.cfg.vision)
        camera = Camera(lighting=Lighting.random(self.rng), noise_sigma=3.0)
        self.renderer = Renderer(look, camera, int(self.rng.integers(2**31)))
        self.tags = fleet_tags(n, self.cfg.vision.aruco.rover_id, self.cfg.vision.aruco.target_id)
        self.locator = FleetLocator(self.cfg.vision, scenario.arena.width_m, scenario.arena.height_m, self.tags)
        self.scene_base = Scene.of_scenario(scenario, "aruco")
        self._pending: collections.deque = collections.deque()
        self._next_frame_s = 0.0
        self._host_ticked = -1.0
        self.frames_rendered = 0
        self.frames_dropped = 0
        self.lost_by_rover = [0] * n
        self.crash: dict | None = None
        self.timed_out = False
        self.stuck = False
        self.min_separation_m = math.inf
        self._legs_done = 0
        self._progress_s = 0.0
        self._moved_s = 0.0
        for r in self.rovers:
            r.anchor = (r.plant.x, r.plant.y)
        self.wall_s = 0.0
        self.uno_timing: dict | None = None  # rover 1 as the Uno image: its step times (cores/uno.py)
        self.frame_sink: Callable | None = None  # (t_s, frame): every frame the camera takes (the video)
        self.tracks: list[list[tuple[float, float]]] = [[] for _ in range(n)]

    def _host_event(self, k: int, t: float, text: str) -> None:
        self.events.append((t, k, text))
        self.progress(t, f"rover {k + 1}: {text}" if k >= 0 else text)

    def _sim_event(self, t: float, text: str) -> None:
        self.events.append((t, -1, text))
        self.progress(t, text)
        if self.runlog is not None:
            self.runlog.shared.event(t, text, level="error" if text.startswith(("CRASH", "stuck")) else "info")

    def _standing(self, k: int, now_s: float) -> str:
        """Where rover k stands and what it waits for, for a stuck fleet's message: its state (the
        last STATUS's), where it truly stands (the simulator's plant), held and why, parked, or done."""
        m, r = self.host.missions[k], self.rovers[k]
        s = m.last_status
        state = mg.RoverState(s.state).name.lower() if s is not None else "not heard"
        text = f"rover {k + 1} {state} at ({r.plant.x:.2f}, {r.plant.y:.2f}) m"
        if m.done:
            return text + ", its mission over"
        if m.parked:
            return text + ", its trips done"
        if m.held:
            return text + f", held {m.held_for_s(now_s):.0f} s ({m.held_why})"
        return text + (f", on leg {len(m.legs)}" if m.legs else "")

    def close_log(self, summary: dict | None = None) -> None:
        """The run log closed and in place (also after a run cut short)."""
        if self.runlog is not None:
            self.runlog.close(summary if summary is not None else self.report())
            self.runlog = None

    # ---------------------------------------------------------------- the loop

    def run(self) -> None:
        wall0 = time.monotonic()
        next_progress = 30.0
        while not self.host.finished and self.crash is None:
            now = self.t
            if now >= self.opt.max_time_s:
                self.timed_out = True
                self._sim_event(now, f"stopped by the time limit ({self.opt.max_time_s:g} s simulated)")
                self.host.fail("the simulator's time limit")
                break
            # (Home from its last leg counts: that leg is marked done when the whole fleet is.)
            done = sum(sum(1 for leg in m.legs if leg.reached) + m.parked for m in self.host.missions)
            if done != self._legs_done:
                self._legs_done, self._progress_s = done, now
            elif (
                now - self._progress_s > STUCK_S and now - self._moved_s > STILL_S
            ) or now - self._progress_s > SLOW_S:
                self.stuck = True
                self._sim_event(
                    now,
                    f"stuck: no rover finished a leg for {now - self._progress_s:.0f} s"
                    + (f", none moved {MOVED_M:g} m in {STILL_S:g} s" if now - self._moved_s > STILL_S else "")
                    + "; "
                    + "; ".join(self._standing(k, now) for k in range(len(self.rovers))),
                )
                self.host.fail("the fleet is stuck")
                break
            self.host_transport.now_s = now
            if self.runlog is not None:
                self.runlog.set_time(now)
            processed = self._camera(now)
            if processed or now - self._host_ticked >= HOST_PERIOD_S:
                self._host_ticked = now
                self.host.tick(now)
            self.host.air(now)
            # Each rover's clock runs on its own: its steps fall at its own phase within the
            # simulator's 10 ms (sliding, as a ceramic resonator's 0.5 % does), and it reads and
            # writes the air at that instant. In the order of their instants, so that the shared
            # air is resolved in time order.
            phases = [(self._phase_s(r, now), r) for r in self.rovers]
            for phase, r in sorted(phases, key=lambda p: p[0]):
                self._rover(r, now, now + phase)
                r.time_s[self.doing(r)] += STEP_S
            self._contacts(now)
            if int(round(now * 1000)) % 100 == 0:
                for r in self.rovers:
                    self.tracks[r.index].append((r.plant.x, r.plant.y))
                    if math.hypot(r.plant.x - r.anchor[0], r.plant.y - r.anchor[1]) >= MOVED_M:
                        r.anchor, self._moved_s = (r.plant.x, r.plant.y), now
            if self.runlog is not None:
                for r, log in zip(self.rovers, self.runlog.rovers):
                    log.true_pose(now + STEP_S, r.plant.x, r.plant.y, r.plant.heading)
            self.t = round(now + STEP_S, 6)
            if self.t >= next_progress:
                next_progress += 30.0
                self.progress(self.t, None)
        self.wall_s = time.monotonic() - wall0
        if self.opt.rover1 == "uno":
            self.uno_timing = self.rovers[0].core.timing()
        for r in self.rovers:
            r.core.close()

    def _camera(self, now: float) -> bool:
        if now + 1e-9 >= self._next_frame_s:
            self._next_frame_s += 1.0 / self.opt.camera_fps
            if self.rng.random() < self.opt.frame_drop:
                self.frames_dropped += 1
            else:
                poses = [(r.plant.x, r.plant.y, r.plant.heading) for r in self.rovers]
                fleet = tuple((*poses[k], self.tags[k + 1]) for k in range(1, len(poses)))
                scene = dataclasses.replace(self.scene_base, rover=poses[0], fleet=fleet)
                frame = self.renderer.render(scene, self.rng)
                self._pending.append((now, frame))
                self.frames_rendered += 1
                if self.frame_sink is not None:
                    self.frame_sink(now, frame)
                if self.runlog is not None:
                    self.runlog.camera_image(now, frame)
        processed = False
        while self._pending and self._pending[0][0] + self.opt.camera_latency_s <= now + 1e-9:
            taken, frame = self._pending.popleft()
            seen = self.locator.locate(frame, taken)
            for k in self.host.on_seen(seen, taken, now):
                self.lost_by_rover[k] += 1
            processed = True
        return processed

    def _sonar_mm(self, r: RoverSim) -> int:
        """A ping: the arena's shapes, and the other rovers' bodies."""
        mm = r.plant.sonar_mm(self.world)
        c = r.plant.cfg
        sx, sy = sonar_origin(r.plant.x, r.plant.y, r.plant.heading, c.sonar_offset_m)
        axis = r.plant.heading + r.plant.servo_deg
        nearest = c.sonar_max_m
        for o in self.rovers:
            if o is r or math.hypot(o.plant.x - sx, o.plant.y - sy) > c.sonar_max_m + 0.2:
                continue
            poly = _corners(o.plant.x, o.plant.y, o.plant.heading)
            for a in np.linspace(-c.sonar_cone_deg / 2, c.sonar_cone_deg / 2, c.sonar_rays):
                nearest = min(nearest, ray_polygon_m(sx, sy, axis + a, poly, nearest))
        if nearest < c.sonar_max_m and (mm == 0 or nearest * 1000 < mm):
            return max(20, int(round(nearest * 1000)))
        return mm

    def _phase_s(self, r: RoverSim, now: float) -> float:
        skew = ROVER_CLOCK_SKEW * (1 + 0.37 * r.index)
        return (now * skew + r.index * STEP_S / (len(self.rovers) + 1)) % STEP_S

    def _rover(self, r: RoverSim, now: float, at: float) -> None:
        """Rover r's step: the simulator's `now` for its plant, `at` (its own clock's step, within
        the same 10 ms) for what it hears and says."""
        rx = r.to_rover.receive(at, 255)
        tx_room = max(0, mg.UART_BUFFER_BYTES - r.to_host.queued())
        out = r.core.step(
            int(round(now * 1000)),
            gyro_rate_mdps=r.plant.gyro_mdps(),
            sonar_range_mm=r.sonar_pending,
            rx=rx,
            tx_room=tx_room,
        )
        # (The Uno image pings the plant itself, through UnoCore's sonar callback.)
        r.sonar_pending = (
            self._sonar_mm(r) if out.fire_sonar and not (r.index == 0 and self.opt.rover1 == "uno") else None
        )
        if out.tx:
            r.to_host.write(out.tx, at)
        x0, y0 = r.plant.x, r.plant.y
        r.plant.step(out.left_pwm, out.right_pwm, out.servo_cdeg, STEP_S)
        r.distance_m += math.hypot(r.plant.x - x0, r.plant.y - y0)
        if r.crash is None and self.world.clearance_bound_m(r.plant.x, r.plant.y) <= 0.05:
            if self.world.clearance_m(r.plant.x, r.plant.y, r.plant.heading) <= 0.0:
                against = self.world.touching(r.plant.x, r.plant.y, r.plant.heading)
                self._crash(r, now, against)

    def doing(self, r: RoverSim) -> str:
        """What rover r does this step, for its time by state (`report`'s `time_s`): the host's
        word first (`held`: stopped by the traffic rules for another rover; `parked`: its trips
        done, waiting for the fleet; `over`: its mission ended), else its firmware's state (the
        core's own, every step: `scan`, `drive`, `rotate`, `blocked`, `back_off`, ...)."""
        m = self.host.missions[r.index]
        if m.done:
            return "over"
        if m.parked:
            return "parked"
        if m.held:
            return "held"
        return mg.RoverState(r.core.probe().state).name.lower()

    def _contacts(self, now: float) -> None:
        rs = self.rovers
        for i in range(len(rs)):
            for j in range(i + 1, len(rs)):
                a, b = rs[i].plant, rs[j].plant
                d = math.hypot(a.x - b.x, a.y - b.y)
                if d < self.min_separation_m:
                    self.min_separation_m = d
                if d < 0.26 and rectangles_touch(_corners(a.x, a.y, a.heading), _corners(b.x, b.y, b.heading)):
                    self._crash(rs[i], now, f"rover {j + 1}")

    def _crash(self, r: RoverSim, now: float, against: str) -> None:
        r.crash = {
            "t_s": round(now, 2),
            "x_m": round(r.plant.x, 3),
            "y_m": round(r.plant.y, 3),
            "heading_deg": round(r.plant.heading, 1),
            "against": against,
        }
        if self.crash is None:
            self.crash = {"rover": r.index + 1, **r.crash}
        self._sim_event(now, f"CRASH: rover {r.index + 1} at ({r.plant.x:.2f}, {r.plant.y:.2f}) m against {against}")
        self.host.fail(f"rover {r.index + 1} touched {against}")

    # ---------------------------------------------------------------- results

    @property
    def outcome(self) -> str:
        if self.crash is not None:
            return "crashed"
        if self.stuck:
            return "stuck"
        if self.timed_out:
            return "timeout"
        if all(m.outcome is Outcome.REACHED for m in self.host.missions):
            return "reached"
        return "failed"

    def trips_done(self, k: int) -> int:
        """Round trips rover k finished (both legs of each; home from its last, parked there, counts)."""
        m = self.host.missions[k]
        return round_trips_done(m.legs, m.parked)

    def report(self) -> dict:
        n = len(self.rovers)
        t = self.t
        rovers = []
        for k, r in enumerate(self.rovers):
            m = self.host.missions[k]
            rovers.append(
                {
                    "rover": k + 1,
                    "outcome": m.outcome.value,
                    "error": m.error,
                    "trips_done": self.trips_done(k),
                    "trips_asked": m.legs_asked // 2,
                    "last_leg_s": round(max((leg.finished_s or 0.0) for leg in m.legs), 2) if m.legs else None,
                    "distance_m": round(r.distance_m, 2),
                    "crash": r.crash,
                    "held": {"times": m.holds, "seconds": round(m.held_s, 1)},
                    "time_s": {what: round(s, 1) for what, s in r.time_s.most_common()},
                    "echoes_of_rovers": m.echoes_of_rovers,
                    "paths_over_seen_ground": m.paths_unswept,
                    "blocked_resends": m.blocked_resends,
                    "camera_lost_frames": self.lost_by_rover[k],
                    "link": self.radio.load[k].summary(t),
                    "link_loss": m.quality.summary(),
                }
            )
        trips = sum(r["trips_done"] for r in rovers)
        return {
            "outcome": self.outcome,
            "rovers": n,
            "mission_time_s": round(t, 2),
            "wall_time_s": round(self.wall_s, 1),
            "trips_done": trips,
            "trips_per_hour": round(trips * 3600.0 / t, 1) if t > 0 else None,
            "contacts": 0 if self.crash is None else 1,
            "crash": self.crash,
            "min_rover_separation_m": round(self.min_separation_m, 3) if n > 1 else None,
            "give_ways": self.host.traffic.give_ways,
            "make_ways": self.host.traffic.make_ways,
            "radio": {
                "air_bytes_per_s": round(
                    sum(x["link"]["to_rover_bytes_per_s"] + x["link"]["from_rover_bytes_per_s"] for x in rovers), 1
                ),
                "unroutable_frames": self.radio.unroutable,
                "slot_s_one_frame": round(grant_air_s(1), 4),
            },
            "per_rover": rovers,
            "uno_timing": self.uno_timing,
        }


def fleet_summary(r: dict) -> str:
    lines = [
        f"{r['outcome'].upper()}: {r['rovers']} rovers, {r['trips_done']} round trips in {r['mission_time_s']:.1f} s "
        f"({r['trips_per_hour']} an hour), {r['contacts']} contacts, closest two rovers came "
        f"{r['min_rover_separation_m']} m apart (centres); air {r['radio']['air_bytes_per_s']:.0f} B/s of 5,760"
    ]
    for x in r["per_rover"]:
        link = x["link"]
        lines.append(
            f"  rover {x['rover']}: {x['outcome']}, {x['trips_done']}/{x['trips_asked']} trips, "
            f"{x['distance_m']:.1f} m, held {x['held']['times']}x ({x['held']['seconds']:.0f} s); "
            f"to it {link['to_rover_bytes_per_s']:.0f} B/s, from it {link['from_rover_bytes_per_s']:.0f} B/s, "
            f"{link['slots_per_s']:.1f} slots/s"
            + _time_shares(x.get("time_s"), r["mission_time_s"])
            + (f"; {x['error']}" if x["error"] else "")
        )
    return "\n".join(lines)


def _time_shares(time_s: dict | None, total_s: float, most: int = 3) -> str:
    """A rover's largest shares of the run's time by what it did (report.json's `time_s`)."""
    if not time_s or total_s <= 0:
        return ""
    top = sorted(time_s.items(), key=lambda kv: -kv[1])[:most]
    return "; time: " + ", ".join(f"{what.replace('_', ' ')} {100 * s / total_s:.0f} %" for what, s in top)
