"""What a simulated mission produced: report.json, the summary picture and the annotated video."""

from __future__ import annotations

import math
import os
from pathlib import Path

import cv2
import numpy as np

from ..arena_picture import Canvas, draw_arena
from ..files import write_atomic, write_json_atomic
from ..link import messages_gen as mg
from ..mission.legs import legs_per_trip
from ..sim.channel import radio_figures
from ..sim.world import footprint

TRIP_COLOURS = [(40, 40, 220), (220, 120, 30), (40, 170, 40), (170, 40, 170), (30, 170, 200)]


def _spl(success: bool, optimal: float | None, driven: float) -> float:
    """Success weighted by (normalised inverse) path length, per episode (Anderson et al. 2018)."""
    if not success or optimal is None or optimal <= 0:
        return 0.0
    return optimal / max(driven, optimal)


def fmt_m(value: float | None) -> str:
    """A length for people: "2.13 m", or "none" where it is undefined (no path exists)."""
    return "none" if value is None else f"{value:.2f} m"


def outcome_text(report: dict) -> str:
    """How a run ended, in a few words."""
    o = report["outcome"]
    if o == "reached":
        return "reached"
    if o == "crashed":
        c = report["crash"]
        return f"CRASHED at {c['t_s']:.1f} s into {c['against']}"
    if o == "no_path":
        return "NOT reached: no path (the host's verdict)"
    if o == "timeout":
        return "NOT reached: stopped by the time limit"
    return "NOT reached: mission failed"


def _r(value: float | None, digits: int) -> float | None:
    """Rounded, or None for an undefined value (report.json is strict JSON: no NaN, no Infinity)."""
    if value is None or not math.isfinite(value):
        return None
    return round(value, digits)


def cruise_speed_m_s(params: list) -> float:
    """The rover's straight-line speed by its own motor model: (drive_pwm - dead band) x speed per PWM,
    from its CONFIG parameters as sent (defaults from the protocol definition)."""
    p = {int(k): v for k, v in params}

    def get(param):
        return p.get(int(param), mg.PARAMS[param].default)

    pwm = get(mg.Param.DRIVE_PWM) - get(mg.Param.MOTOR_DEADBAND_PWM)
    return (
        max(pwm, 0) * get(mg.Param.SPEED_MM_S_PER_PWM_X1000) / mg.PARAMS[mg.Param.SPEED_MM_S_PER_PWM_X1000].scale / 1000
    )


def build_report(sim, wall_time_s: float) -> dict:
    m = sim.mission
    sc = sim.scenario
    legs = []
    driven_total = 0.0
    for trip in m.legs:
        pts = [s for s in sim.samples if s.trip == trip.index]
        driven = sum(math.dist((a.x_m, a.y_m), (b.x_m, b.y_m)) for a, b in zip(pts, pts[1:]))
        driven_total += driven
        optimal = sim.trip_optimal_m(trip.index)
        end = trip.finished_s if trip.finished_s is not None else sim.t
        legs.append(
            {
                "index": trip.index + 1,
                "goal": [round(trip.goal[0], 3), round(trip.goal[1], 3)],
                "reached": trip.reached,
                "time_s": round(end - trip.started_s, 2),
                "path_length_m": round(driven, 3),
                "optimal_length_m": _r(optimal, 3),
                "spl": round(_spl(trip.reached, optimal, driven), 3),
                "replans": trip.replans,
                "sonar_echoes": trip.obstacles_found,
                "planned_length_m": round(trip.planned_length_m, 3),
            }
        )
    reached = len(m.legs) == m.legs_asked and all(leg["reached"] for leg in legs)
    # A trip: one leg for a reach mission, out and back (two legs) for an out-and-back one.
    per_trip = legs_per_trip(sc.mission.kind)
    trips = []
    for i in range(0, len(legs), per_trip):
        group = legs[i : i + per_trip]
        trips.append(
            {
                "index": i // per_trip + 1,
                "reached": len(group) == per_trip and all(g["reached"] for g in group),
                "time_s": round(sum(g["time_s"] for g in group), 2),
                "path_length_m": round(sum(g["path_length_m"] for g in group), 3),
                "optimal_length_m": None
                if any(g["optimal_length_m"] is None for g in group)
                else round(sum(g["optimal_length_m"] for g in group), 3),
                "replans": sum(g["replans"] for g in group),
                "legs": [g["index"] for g in group],
            }
        )
    status = m.last_status
    c = sim.link.counters
    unknown = [o for o in _shapes(sc) if not o.known]
    discovered = sum(1 for o in unknown if _echo_on(o, m.echoes, m.grid.config.sonar_offset_m))
    optimal = sim.optimal_length_m()
    speed = cruise_speed_m_s(m.rover_params)
    return {
        "scenario": sc.name,
        "scenario_meta": getattr(sc, "generated", None),
        "strategy": sim.opt.strategy,
        "drive_mode": sim.drive_mode,
        "seed": sim.opt.seed,
        "reached": reached,
        "outcome": sim.outcome,
        "crashed": sim.crash is not None,
        "crash": sim.crash,
        "timed_out": sim.timed_out,
        "trips_asked": m.legs_asked // per_trip,
        "legs_asked": m.legs_asked,
        "collisions": sim.collisions,
        "mission_time_s": round(sim.t, 2),
        "wall_time_s": round(wall_time_s, 2),
        "speedup": round(sim.t / wall_time_s, 1) if wall_time_s > 0 else None,
        "path_length_m": round(driven_total, 3),
        "optimal_length_m": _r(optimal, 3),
        "cruise_speed_m_s": round(speed, 4),
        "optimal_time_s": _r(optimal / speed, 2) if optimal is not None and speed > 0 else None,
        "spl": round(sum(leg["spl"] for leg in legs) / max(1, m.legs_asked), 3),
        "min_clearance_m": round(sim.min_clearance_m, 4) if math.isfinite(sim.min_clearance_m) else None,
        "replans": m.replans,
        "obstacles_discovered": discovered,
        "obstacles_unknown": len(unknown),
        "sonar_echoes": len(m.echoes),
        "error": m.error,
        "failure": m.failure.value if m.failure is not None else None,
        "trips": trips,
        "legs": legs,
        "camera": {
            "fps": sim.opt.camera_fps,
            "latency_s": sim.opt.camera_latency_s,
            "frames": sim.frames_rendered,
            "dropped": sim.frames_dropped,
            "fixes_sent": m.fixes_sent,
        },
        "link": {
            "baud": sim.opt.channel.baud,
            "delay_s": sim.opt.channel.delay_s,
            "to_rover": sim.to_rover.byte_counters(),
            "to_host": sim.to_host.byte_counters(),
            "host_decoder": {
                "frames_ok": c.frames_ok,
                "bad_crc": c.bad_crc,
                "overlong": c.overlong,
                "unknown_id": c.unknown_id,
                "malformed": c.malformed,
            },
            "rover_decoder": None
            if status is None
            else {
                "frames_ok": status.rx_ok,
                "bad_crc": status.rx_bad_crc,
                "overlong": status.rx_overlong,
                "unknown_id": status.rx_unknown_id,
                "malformed": status.rx_malformed,
                "tx_dropped": status.tx_dropped,
            },
            "signing": signing_figures(sim),
            # As the host measured it (what `rovernav run` shows too): frames through both ways,
            # and what it sent and sent again, per message kind.
            "quality": m.link_summary(),
        },
        # The radio as set, and what it did each way (bytes, frames by message kind, bursts).
        "radio": radio_figures(sim.to_rover, sim.to_host, sim.t),
        "faults": fault_figures(sim),
        "setup": setup_figures(sim.opt.setup),
        "events": [{"t_s": round(t, 2), "text": text} for t, text in sim.events],
    }


def setup_figures(setup) -> dict | None:
    """report.json's "setup": a set-up that is not the defaults (`rovernav sim --setup SEED`), as
    drawn: the markers' colour words and BGR, the light, where the camera sees the corners, the
    plant's motor and gyro figures. None for the usual set-up."""
    if setup is None:
        return None
    p = setup.plant
    return {
        "seed": setup.seed,
        "colours": setup.colour_words(),
        "bgr": {
            "rover_front": list(setup.front_bgr),
            "rover_back": list(setup.back_bgr),
            "target": list(setup.target_bgr),
        },
        "light_level": None if setup.lighting is None else round(setup.lighting.level, 3),
        "corners_px": None if setup.corners_px is None else [[round(u, 2), round(v, 2)] for u, v in setup.corners_px],
        "plant": {
            "mm_s_per_pwm": round(p.mm_s_per_pwm, 3),
            "right_gain": round(p.right_gain, 3),
            "deadband_pwm": round(p.deadband_pwm, 2),
            "gyro_bias_dps": round(p.gyro_bias_dps, 3),
        },
    }


def signing_figures(sim) -> dict:
    """Whether the link was signed, what each end refused for its signature, and what the attacker
    (if any) injected: each injected frame should be refused by the rover, by the reason expected."""
    hc = sim.link.counters
    out = {
        "signed": sim.link_key is not None,
        "rover_refused": sim.core.auth_counters(),
        # the native core is asked; the Uno image's counts are those of its last LINK_AUTH, sent
        # in STATUS's place when they change (a refusal in the last 0.2 s may not be in it)
        "rover_counts_from": "core" if sim.opt.rover == "native" else "last LINK_AUTH",
        "host_refused": {
            "bad_tag": hc.bad_tag,
            "replayed": hc.replayed,
            "not_signed": hc.not_signed,
            "unverified": hc.unverified,
        },
    }
    if sim.attacker is not None:
        from ..sim.attacker import EXPECTED_REFUSAL

        expected: dict[str, int] = {}
        for kind, n in sim.attacker.injected.items():
            reason = (
                EXPECTED_REFUSAL[kind] if sim.link_key is not None else ("unverified" if kind == "forged" else None)
            )
            if reason is not None:  # unsigned: the rest is obeyed
                expected[reason] = expected.get(reason, 0) + n
        refused = out["rover_refused"]
        out["attacker"] = {
            "injected": dict(sim.attacker.injected),
            "injected_total": sum(sim.attacker.injected.values()),
            "refused_total": sum(refused[k] for k in ("bad_tag", "replayed", "not_signed", "unverified")),
            "expected_refusals": expected,
        }
    return out


def fault_figures(sim) -> dict:
    """What was injected and what the rover did about it, from its EVENTs (as the host got them)."""
    f = sim.opt.faults
    events = [(t, e) for t, e in sim.mission.events]

    def of(kind):
        return [(t, e) for t, e in events if e.kind == kind]

    dr_errors = [e.arg / 1000 for _, e in of(mg.EventKind.CAMERA_BACK)]
    # Safe stops from the rover's own state (sampled through the core's probe, for the report
    # only): its HOLD events are lost when the radio is what failed.
    holds, recoveries = [], []
    in_hold = None
    for smp in sim.samples:
        if smp.state == mg.RoverState.HOLD and in_hold is None:
            in_hold = smp
            holds.append(
                {
                    "t_s": round(smp.t_s, 2),
                    "x_m": round(smp.x_m, 3),
                    "y_m": round(smp.y_m, 3),
                    "uncertainty_2sd_m": round(2 * smp.est[3], 3) if smp.est else None,
                }
            )
        elif smp.state != mg.RoverState.HOLD and in_hold is not None:
            recoveries.append(round(smp.t_s - in_hold.t_s, 2))
            in_hold = None
    if in_hold is not None:
        recoveries.append(None)
    return {
        "injected": {
            "link_outages": f.link_outages,
            "camera_outages": f.camera_outages,
            "camera_outage_kind": f.camera_outage_kind,
            "host_restarts": f.host_restarts,
            "firmware_resets": f.firmware_resets,
            "gyro_dies_at": f.gyro_dies_at,
        },
        "dr_errors_m": dr_errors,
        "max_dr_error_m": max(dr_errors) if dr_errors else None,
        "holds": holds,
        "hold_recovery_s": recoveries,
        "link_lost_events": len(of(mg.EventKind.LINK_LOST)),
        "camera_lost_events": len(of(mg.EventKind.CAMERA_LOST)),
        "rover_faults": [
            {
                "t_s": round(e.time_ms / 1000, 2),
                "fault": mg.FaultCode(e.arg).name.lower() if e.arg in mg.FaultCode._value2member_map_ else e.arg,
            }
            for _, e in of(mg.EventKind.FAULT)
        ],
        "local_detours": sum(1 for _, e in of(mg.EventKind.REPLANNED) if e.arg > 0),
        "reflex_stops": len(of(mg.EventKind.REFLEX)),
        "turns_refused": len(of(mg.EventKind.TURN_REFUSED)),
    }


def _shapes(scenario) -> tuple:
    """Every obstacle of the scenario: boxes, walls, posts."""
    return (*scenario.obstacles, *getattr(scenario, "walls", ()), *getattr(scenario, "posts", ()))


def _echo_on(obstacle, echoes, offset_m: float, margin_m: float = 0.06) -> bool:
    """Whether some sonar echo's point lies on (near) this obstacle: within margin_m of a wall or
    a post, inside a box grown by margin_m on every side."""
    for e in echoes:
        px, py = e.point(offset_m)
        if getattr(obstacle, "kind", "box") != "box":
            if obstacle.distance_m(px, py) <= margin_m:
                return True
        elif (
            abs(px - obstacle.x_m) <= obstacle.w_m / 2 + margin_m
            and abs(py - obstacle.y_m) <= obstacle.h_m / 2 + margin_m
        ):
            return True
    return False


# ---------------------------------------------------------------- pictures


def summary_picture(sim, report: dict, path: Path) -> None:
    sc = sim.scenario
    canvas = Canvas(sc.arena.width_m, sc.arena.height_m)
    draw_arena(canvas, sim, sim.mission.grid)
    img = canvas.img
    for trip in sim.mission.legs:
        pts = [(s.x_m, s.y_m) for s in sim.samples if s.trip == trip.index]
        if len(pts) > 1:
            cv2.polylines(img, [canvas.pts(pts)], False, TRIP_COLOURS[trip.index % len(TRIP_COLOURS)], 2, cv2.LINE_AA)
    if sim.samples:
        s = sim.samples[-1]
        cv2.polylines(img, [canvas.pts(footprint(s.x_m, s.y_m, s.heading_deg))], True, (20, 20, 20), 2)
    footer = np.full((70, img.shape[1], 3), 255, np.uint8)
    lines = [
        f"{report['scenario']} / {report['strategy']}: {outcome_text(report)}, "
        f"{report['mission_time_s']:.1f} s, {report['path_length_m']:.2f} m driven "
        f"(optimal {fmt_m(report['optimal_length_m'])}), SPL {report['spl']:.2f}",
        f"collisions {report['collisions']}, min clearance {report['min_clearance_m'] or 0:.3f} m, "
        f"replans {report['replans']}, unknown obstacles found {report['obstacles_discovered']}/"
        f"{report['obstacles_unknown']}; trips: "
        + ", ".join(f"{t['index']}: {t['time_s']:.0f} s, {t['replans']} replans" for t in report["trips"]),
    ]
    for i, line in enumerate(lines):
        cv2.putText(footer, line, (10, 25 + 28 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (30, 30, 30), 1, cv2.LINE_AA)
    ok, png = cv2.imencode(".png", np.vstack([img, footer]))
    if not ok:
        raise RuntimeError("OpenCV could not encode the summary picture")
    write_atomic(Path(path), png.tobytes())


class VideoWriter:
    """The camera's frames, annotated: path, known and found obstacles, true and estimated pose,
    sonar hits, heading; written at the camera's rate as H.264 through PyAV (libx264, yuv420p, the
    index at the front of the file so that a browser plays it while it loads).

    Only the video is filtered: the annotations go on a copy of each frame, and the host's frames
    stay the camera's, sensor noise and all. What the encoder is told (encoder_options) keeps
    out-and-back's 198 s of video at 640x480, 30 fps, to 2.9 MB (the OpenCV mp4v video was 26 MB)
    with the status line and the lines legible; benchmarks/bench_video.py measures it. The heading
    arrows and the estimate's circle are 2 px wide: at 1 px their green and cyan, about as bright
    as the floor, went grey in 4:2:0 chroma (in the mp4v video too).
    """

    CRF_DEFAULT = 20
    PRESET_DEFAULT = "veryfast"
    # H.264 encoders tried in turn: libx264 (in PyAV's wheels), else OpenH264 (some FFmpeg builds).
    ENCODERS = ("libx264", "libopenh264")

    def __init__(self, path: Path, fps: float, *, crf: float | None = None, preset: str | None = None):
        self.path = Path(path)
        # Frames go to a hidden partial file, renamed into place by close(): a run cut short
        # leaves no half video under the real name.
        self.partial = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self.fps = fps
        self.crf = self.CRF_DEFAULT if crf is None else crf
        self.preset = preset or self.PRESET_DEFAULT
        self.container = None  # av.container.OutputContainer once the first frame came
        self.stream = None
        self.codec = None  # the encoder's name, "libx264" (or the fall-back's)
        self.frames = 0
        self._cal = None

    def __call__(self, t_s: float, frame: np.ndarray, sim) -> None:
        self.write(self.annotate(t_s, frame, sim))

    def annotate(self, t_s: float, frame: np.ndarray, sim) -> np.ndarray:
        """An annotated copy of a camera frame (the frame itself is left as the host sees it)."""
        from ..vision.calibration import Calibration

        img = frame.copy()
        h, w = img.shape[:2]
        sc = sim.scenario
        key = (w, h, sc.arena.width_m, sc.arena.height_m)
        if self._cal is None or self._cal[0] != key:
            self._cal = (key, Calibration.straight_down(w, h, sc.arena.width_m, sc.arena.height_m))
        cal = self._cal[1]

        def pxs(points) -> np.ndarray:
            """Arena points (metres) to the nearest pixel centres, N x 2 int32, in one go."""
            return np.rint(cal.to_pixels(np.asarray(points, np.float64).reshape(-1, 2))).astype(np.int32)

        def px(x, y):
            u, v = pxs((x, y))[0]
            return int(u), int(v)

        m = sim.mission
        if m.path:
            cv2.polylines(img, [pxs(m.path)], False, (255, 0, 255), 2, cv2.LINE_AA)
        for o in sc.obstacles:
            color = (200, 200, 200) if o.known else (80, 80, 255)
            cv2.rectangle(
                img, px(o.x_m - o.w_m / 2, o.y_m + o.h_m / 2), px(o.x_m + o.w_m / 2, o.y_m - o.h_m / 2), color, 1
            )
        # Walls and posts: the camera's renderer does not draw them (its Scene holds boxes only),
        # so the overlay draws them filled, known grey, unknown red.
        for o in getattr(sc, "walls", ()):
            color = (200, 200, 200) if o.known else (80, 80, 255)
            cv2.fillPoly(img, [pxs(o.corners())], color, cv2.LINE_AA)
        for o in getattr(sc, "posts", ()):
            color = (200, 200, 200) if o.known else (80, 80, 255)
            (u, v), (u1, _) = px(o.x_m, o.y_m), px(o.x_m + o.radius_m, o.y_m)
            cv2.circle(img, (u, v), max(1, abs(u1 - u)), color, -1, cv2.LINE_AA)
        offset = m.grid.config.sonar_offset_m
        for u, v in pxs([e.point(offset) for e in m.echoes[-60:]]).tolist():
            cv2.circle(img, (u, v), 3, (0, 0, 255), -1)
        p = sim.plant
        cv2.polylines(img, [pxs(footprint(p.x, p.y, p.heading))], True, (0, 255, 0), 1)
        hr = math.radians(p.heading)
        cv2.arrowedLine(img, px(p.x, p.y), px(p.x + 0.15 * math.sin(hr), p.y + 0.15 * math.cos(hr)), (0, 255, 0), 2)
        st = m.last_status
        if st is not None and st.flags & mg.StatusFlag.MISSION_ACTIVE:
            ex, ey = st.x_mm / 1000, st.y_mm / 1000
            sd = max(st.sd_x_mm, st.sd_y_mm) / 1000
            cv2.circle(img, px(ex, ey), max(2, int(2 * sd * w / sc.arena.width_m)), (255, 200, 0), 2)
            eh = math.radians(st.heading_cdeg / 100)
            cv2.arrowedLine(img, px(ex, ey), px(ex + 0.12 * math.sin(eh), ey + 0.12 * math.cos(eh)), (255, 200, 0), 2)
            state = mg.RoverState(st.state).name.lower() if st.state in mg.RoverState._value2member_map_ else st.state
        else:
            state = "-"
        text = f"t {t_s:6.1f} s  leg {len(m.legs)}  {state}  replans {m.replans}  collisions {sim.collisions}"
        cv2.rectangle(img, (0, 0), (w, 22), (0, 0, 0), -1)
        cv2.putText(img, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        return img

    def encoder_options(self) -> dict[str, str]:
        """libx264's options, chosen on out-and-back. Constant quality (CRF) rather than a bitrate:
        the arena stands still and the bits go where the rover moves. What costs bits is the
        camera's noise (3 grey levels; each frame one of eight noisy copies of the arena): with
        preset veryfast alone the video is 28 MB at CRF 18, 8.4 MB at CRF 20, 2.0 MB at CRF 23.
        tune=animation (flat areas and sharp edges: stronger deblocking, more reference frames and
        B-frames) and a wider dead zone for inter-coded coefficients (32 against 21: the small noise
        coefficients go to zero, the edges' large ones stay) bring CRF 20 to 2.9 MB. The annotations'
        pixels then come back within 33.6 dB PSNR of the frame in 4:2:0 (the status line 43.5 dB),
        the old mp4v video's 34.0 (45.5) at 26 MB. The dead zone only acts without trellis
        quantisation, as in veryfast; slower presets also spend their effort keeping noise (medium
        makes a bigger file than veryfast) and cost more time."""
        return {"crf": f"{self.crf:g}", "preset": self.preset, "tune": "animation", "x264-params": "deadzone-inter=32"}

    def _open(self, w: int, h: int) -> None:
        from fractions import Fraction

        import av

        rate = Fraction(self.fps).limit_denominator(1001)
        tried = []
        for codec in self.ENCODERS:
            container = av.open(str(self.partial), "w", format="mp4", options={"movflags": "+faststart"})
            try:
                stream = container.add_stream(codec, rate=rate)
                stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
                stream.time_base = 1 / rate
                if codec == "libx264":
                    stream.options = self.encoder_options()
                    # Frame threads (PyAV's default is slice threads, where each encode call waits
                    # for its frame): x264 codes on its own threads while the simulation goes on.
                    stream.codec_context.thread_type = "FRAME"
                    stream.codec_context.thread_count = 0  # x264's own choice (1.5 per core)
                else:  # OpenH264 has no CRF: a bitrate that keeps out-and-back under 5 MB
                    stream.bit_rate = 150_000
                    stream.gop_size = max(1, int(round(10 * self.fps)))
                stream.codec_context.open()  # now, not at the first frame: a failure here falls back
            except (av.FFmpegError, ValueError) as exc:  # not in this FFmpeg build, or it will not open
                tried.append(f"{codec}: {exc}")
                container.close()
                self.partial.unlink(missing_ok=True)
                continue
            except BaseException:
                container.close()
                self.partial.unlink(missing_ok=True)
                raise
            self.container, self.stream, self.codec = container, stream, codec
            return
        raise RuntimeError(
            f"cannot write video {self.path}: the FFmpeg inside PyAV {av.__version__} has no "
            f"H.264 encoder that works ({'; '.join(tried)}); install PyAV's own wheel "
            f"(`pip install av`, it bundles libx264) or run without video (--no-video)"
        )

    def write(self, img: np.ndarray) -> None:
        """Encodes one annotated BGR frame (the next at the camera's rate)."""
        import av

        h, w = img.shape[:2]
        if self.container is None:
            self._open(w, h)
        vf = av.VideoFrame.from_ndarray(img, format="bgr24")
        vf.pts = self.frames
        self.container.mux(self.stream.encode(vf))
        self.frames += 1

    def close(self, keep: bool = True) -> None:
        """Ends the video: moved to its name when `keep`, deleted otherwise (a run that failed).
        If ending it fails, nothing is left either."""
        if self.container is None:
            return
        container, stream = self.container, self.stream
        self.container = self.stream = None
        try:
            try:
                if keep:
                    container.mux(stream.encode(None))  # what the encoder still holds
            finally:
                container.close()
        except BaseException:
            self.partial.unlink(missing_ok=True)
            raise
        if keep:
            os.replace(self.partial, self.path)
        else:
            self.partial.unlink(missing_ok=True)


def write_report(report: dict, path: Path) -> None:
    """report.json: strict JSON (undefined values are null), written atomically."""
    write_json_atomic(path, report)
