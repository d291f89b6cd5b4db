"""The host's configuration: one TOML file, validated on load.

    [arena]    width_m, height_m                       the arena the camera watches
    [link]     port, baud                              the radio's serial port
    [camera]   source (index or video file), fps       the overhead camera
    [vision]   markers, HSV ranges, calibration, ...   (rovernav.vision.config.VisionConfig)
    [planner]  resolution_m, robot_radius_m, ...       (rovernav.planning.PlannerConfig)
    [mission]  trips, heartbeat_hz, fix_sd_mm, fix_hz, map, planner   what the mission does
    [rover]    any CONFIG parameter by name = value    sent to the rover at the start
    [radio]    loss_pct, ber_pct, burst_mean_s,        the simulated radio (`rovernav sim`; its
               burst_share, jitter_ms, half_duplex     --radio-* flags win over these)

Every section and key is optional; a missing one takes its default. An unknown section or key,
or a value of the wrong type or out of range, raises ConfigError naming it
("config.toml: [rover] drive_pwm = 300 is outside [0, 255]").
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any

from . import vehicle_gen as vehicle
from .errors import InputError
from .link import messages_gen as mg
from .validate import MAX_ARENA_M, MAX_TRIPS, check_number, read_text_file

# The global planners a mission may use (rovernav.planning.plan); the potential field is the seed
# report's comparison, not a mission's planner.
MISSION_PLANNERS = ("astar", "theta")


class ConfigError(InputError):
    """A configuration file or value is wrong; the message names the file, section and key."""


@dataclasses.dataclass(frozen=True)
class ArenaConfig:
    width_m: float = vehicle.DEFAULT_ARENA_WIDTH_MM / 1000.0  # the seed's test area (protocol/vehicle.toml)
    height_m: float = vehicle.DEFAULT_ARENA_HEIGHT_MM / 1000.0


@dataclasses.dataclass(frozen=True)
class LinkConfig:
    port: str = ""
    baud: int = vehicle.LINK_BAUD
    key_file: str = (
        ""  # the link key for signed frames (`rovernav keygen`, stored on the rover by `rovernav provision`)
    )


@dataclasses.dataclass(frozen=True)
class CameraConfig:
    source: str = "0"
    fps: float = 30.0


# [mission] fix_hz: the rover must get FIXES_PER_TIMEOUT fixes inside its fix_timeout_ms (500 ms
# by default: at least 6 a second), so that two lost in a row (a signed FIX is 30 bytes: at 1 % of
# bytes lost a quarter of them are) do not put it into dead reckoning; at most MAX_FIX_HZ.
FIXES_PER_TIMEOUT = 3
MAX_FIX_HZ = 120.0


def min_fix_hz(fix_timeout_ms: int = mg.PARAMS[mg.Param.FIX_TIMEOUT_MS].default) -> float:
    """The least [mission] fix_hz for a rover whose fix_timeout_ms is this."""
    return FIXES_PER_TIMEOUT * 1000.0 / fix_timeout_ms


MIN_FIX_HZ = min_fix_hz()  # with the rover's default fix_timeout_ms


@dataclasses.dataclass(frozen=True)
class MissionConfig:
    trips: int = 0  # 0: as the scenario says
    heartbeat_hz: float = 5.0
    fix_sd_mm: int = 3  # one-sigma of a camera fix, sent in FIX
    # FIXes a second at most (a fleet's or a slow radio's airtime); 0: one for every camera frame
    # that sees the rover. At least min_fix_hz(the rover's fix_timeout_ms): 6 by default.
    fix_hz: float = 0.0
    map: str = ""  # a learned map to load at the start and save at the end
    planner: str = "astar"  # the host's global planner: "astar" (16 directions) or "theta" (any angle, Theta*)


@dataclasses.dataclass(frozen=True)
class RadioConfig:
    """The simulated radio (rovernav.radio's model): `rovernav sim` only; hardware has its own."""

    loss_pct: float = 0.0  # mean share of bytes lost [%]
    ber_pct: float = 0.0  # mean share of bytes arriving with one bit flipped [%]
    burst_mean_s: float = 0.0  # mean burst length [s]; 0: no bursts
    burst_share: float = 0.0  # share of time in bursts, in (0, 1) with bursts
    jitter_ms: float = 0.0  # mean extra delay per frame [ms] (exponential)
    half_duplex: bool = False  # both ends share one medium: bytes sent at once collide


@dataclasses.dataclass(frozen=True)
class Config:
    arena: ArenaConfig = ArenaConfig()
    link: LinkConfig = LinkConfig()
    camera: CameraConfig = CameraConfig()
    mission: MissionConfig = MissionConfig()
    vision: Any = None  # VisionConfig
    planner: Any = None  # PlannerConfig
    rover: dict = dataclasses.field(default_factory=dict)  # Param -> int
    radio: RadioConfig = RadioConfig()

    def rover_params(self) -> list[tuple[mg.Param, int]]:
        return sorted(self.rover.items())


def _typed(section: str, key: str, value: Any, want: type, where: str) -> Any:
    if want is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if want is str and isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, want) or isinstance(value, bool) and want is not bool:
        raise ConfigError(f"{where}[{section}] {key} = {value!r} should be {want.__name__}")
    if want is float and not math.isfinite(value):
        raise ConfigError(f"{where}[{section}] {key} = {value!r} should be a finite number")
    if want is str and (len(value) > 4096 or any(ord(c) < 32 for c in value)):
        raise ConfigError(f"{where}[{section}] {key}: a string of {len(value)} characters, or with control characters")
    return value


def _section(cls, section: str, table: Any, where: str, limits: dict | None = None):
    """A section's dataclass from its table. `limits`: key -> (lo, hi, lo_open) for numbers, or a
    set of the allowed values."""
    if not isinstance(table, dict):
        raise ConfigError(f"{where}[{section}] should be a table")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in table.items():
        if key not in fields:
            raise ConfigError(f"{where}[{section}] has no key {key!r} (known: {', '.join(fields)})")
        want = type(getattr(cls(), key))
        kwargs[key] = _typed(section, key, value, want, where)
        rule = (limits or {}).get(key)
        if isinstance(rule, (set, frozenset)):
            if kwargs[key] not in rule:
                raise ConfigError(
                    f"{where}[{section}] {key} = {value!r} must be one of {', '.join(map(str, sorted(rule)))}"
                )
        elif rule is not None:
            lo, hi, lo_open = rule
            try:
                check_number(f"{where}[{section}] {key}", kwargs[key], lo, hi, lo_open=lo_open)
            except InputError as exc:
                raise ConfigError(str(exc)) from None
    return cls(**kwargs)


def config_from_dict(data: dict, where: str = "") -> Config:
    """Build and validate a Config from a parsed TOML document; `where` prefixes messages."""
    from .planning import PlannerConfig
    from .vision.config import VisionConfig

    known = {"arena", "link", "camera", "vision", "planner", "mission", "rover", "radio"}
    for name in data:
        if name == "sonar":  # where the ranger sits is the planner's (and the rover's) geometry
            raise ConfigError(
                f"{where}[sonar] is gone: the ranger's offset is [planner] sonar_offset_m (metres), "
                "which the host plans with and sends to the rover"
            )
        if name not in known:
            raise ConfigError(f"{where}unknown section [{name}] (known: {', '.join(sorted(known))})")
    arena = _section(
        ArenaConfig,
        "arena",
        data.get("arena", {}),
        where,
        {"width_m": (0.0, MAX_ARENA_M, True), "height_m": (0.0, MAX_ARENA_M, True)},
    )
    link = _section(
        LinkConfig, "link", data.get("link", {}), where, {"baud": frozenset((9600, 19200, 38400, 57600, 115200))}
    )
    camera = _section(CameraConfig, "camera", data.get("camera", {}), where, {"fps": (0.0, 120.0, True)})
    mission = _section(
        MissionConfig,
        "mission",
        data.get("mission", {}),
        where,
        {
            "trips": (0, MAX_TRIPS, False),
            "heartbeat_hz": (0.0, 50.0, True),
            "fix_sd_mm": (1, 255, False),
            "fix_hz": (0.0, MAX_FIX_HZ, False),
            "planner": frozenset(MISSION_PLANNERS),
        },
    )
    try:
        vision = VisionConfig.from_dict(data.get("vision", {}))
    except ValueError as exc:
        raise ConfigError(f"{where}[vision] {exc}") from None
    if isinstance(data.get("planner"), dict) and "sonar_max_range_m" in data["planner"]:
        raise ConfigError(
            f"{where}[planner] sonar_max_range_m is gone: the sensor's range is the protocol's "
            f"(protocol/vehicle.toml: sonar_max_range_mm = {vehicle.SONAR_MAX_RANGE_MM}); [rover] sonar_report_mm says how "
            "far the rover reports"
        )
    try:
        planner = PlannerConfig.from_dict(data.get("planner", {}))
    except ValueError as exc:
        raise ConfigError(f"{where}[planner] {exc}") from None
    rover: dict = {}
    table = data.get("rover", {})
    if not isinstance(table, dict):
        raise ConfigError(f"{where}[rover] should be a table")
    by_name = {spec.name: param for param, spec in mg.PARAMS.items()}
    for key, value in table.items():
        if key not in by_name:
            raise ConfigError(f"{where}[rover] has no parameter {key!r}; `rovernav protocol` lists them")
        spec = mg.PARAMS[by_name[key]]
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigError(f"{where}[rover] {key} = {value!r} should be an integer ({spec.unit})")
        if not spec.min <= value <= spec.max:
            raise ConfigError(f"{where}[rover] {key} = {value} is outside [{spec.min}, {spec.max}] ({spec.unit})")
        rover[by_name[key]] = value
    check_pose_gains(rover, where)
    timeout_ms = rover.get(mg.Param.FIX_TIMEOUT_MS, mg.PARAMS[mg.Param.FIX_TIMEOUT_MS].default)
    if 0.0 < mission.fix_hz < min_fix_hz(timeout_ms):
        raise ConfigError(
            f"{where}[mission] fix_hz = {mission.fix_hz:g}: 0 (a fix for every frame) or at least "
            f"{min_fix_hz(timeout_ms):g} a second ({FIXES_PER_TIMEOUT} within the rover's fix_timeout_ms, "
            f"{timeout_ms} ms, after which it dead-reckons)"
        )
    radio = _radio(data.get("radio", {}), where)
    return Config(arena, link, camera, mission, vision, planner, rover, radio)


def _radio(table: Any, where: str) -> RadioConfig:
    """[radio]: each value in its range, then together as rovernav.radio.radio_config
    checks them (bursts need both keys; the loss inside bursts cannot pass 100 %)."""
    from .radio import MAX_BURST_MEAN_S, MAX_JITTER_MS, radio_config

    radio = _section(
        RadioConfig,
        "radio",
        table,
        where,
        {
            "loss_pct": (0.0, 100.0, False),
            "ber_pct": (0.0, 100.0, False),
            "burst_mean_s": (0.0, MAX_BURST_MEAN_S, False),
            "burst_share": (0.0, 1.0, False),
            "jitter_ms": (0.0, MAX_JITTER_MS, False),
        },
    )
    try:
        radio_config(**dataclasses.asdict(radio), names={k: f"{where}[radio] {k}" for k in dataclasses.asdict(radio)})
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    return radio


def check_pose_gains(rover: dict, where: str) -> None:
    """The moving-to-a-pose gains the rover would run with (the file's over the defaults) must be
    stable, by the rule `rovernav pose` applies: a rover must not be sent gains the study refuses."""
    from .control import PoseGains

    keys = (mg.Param.POSE_K_RHO_X1000, mg.Param.POSE_K_ALPHA_X1000, mg.Param.POSE_K_BETA_X1000)
    if not any(k in rover for k in keys):
        return
    k_rho, k_alpha, k_beta = (mg.PARAMS[k].to_value(rover.get(k, mg.PARAMS[k].default)) for k in keys)
    try:
        PoseGains(k_rho=k_rho, k_alpha=k_alpha, k_beta=k_beta)
    except ValueError as exc:
        raise ConfigError(
            f"{where}[rover] pose_k_rho_x1000, pose_k_alpha_x1000, pose_k_beta_x1000 "
            f"({k_rho:g}, {k_alpha:g}, {k_beta:g}): {exc}"
        ) from None


def load_config(path: str | Path | None) -> Config:
    """Read a TOML configuration file (None: every default)."""
    if path is None:
        return config_from_dict({})
    path = Path(path)
    return config_from_dict(read_config_data(path), where=f"{path}: ")


def read_config_data(path: str | Path) -> dict:
    """A TOML configuration file's tables as read, before they are checked (`config_from_dict`
    checks them); ConfigError (one line) for a file that cannot be read or is not TOML."""
    path = Path(path)
    try:
        text = read_text_file(path, "configuration file")
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    if len(text) > 1_000_000:
        raise ConfigError(f"{path}: {len(text):,} characters is not a configuration file (the limit is 1,000,000)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
