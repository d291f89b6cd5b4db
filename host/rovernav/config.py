"""The host's configuration: one TOML file, validated on load.

    [arena]    width_m, height_m                       the arena the camera watches
    [link]     port, baud                              the radio's serial port
    [camera]   source (index or video file), fps       the overhead camera
    [vision]   markers, HSV ranges, calibration, ...   (rovernav.vision.config.VisionConfig)
    [planner]  resolution_m, robot_radius_m, ...       (rovernav.planning.PlannerConfig)
    [sonar]    offset_m                                where the sensor sits ahead of the rover's centre
    [mission]  trips, heartbeat_hz, fix_sd_mm, map     what the mission does
    [rover]    any CONFIG parameter by name = value    sent to the rover at the start

Every section and key is optional; a missing one takes its default. An unknown section or key,
or a value of the wrong type or out of range, raises ConfigError naming it
("config.toml: [rover] drive_pwm = 300 is outside [0, 255]").
"""
from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import Any

from .errors import InputError
from .link import messages_gen as mg


class ConfigError(InputError):
    """A configuration file or value is wrong; the message names the file, section and key."""


@dataclasses.dataclass(frozen=True)
class ArenaConfig:
    width_m: float = 2.36   # the seed's test area
    height_m: float = 1.75


@dataclasses.dataclass(frozen=True)
class LinkConfig:
    port: str = ""
    baud: int = 57600


@dataclasses.dataclass(frozen=True)
class CameraConfig:
    source: str = "0"
    fps: float = 30.0


@dataclasses.dataclass(frozen=True)
class SonarConfig:
    offset_m: float = 0.10  # the HC-SR04 sits this far ahead of the rover's centre


@dataclasses.dataclass(frozen=True)
class MissionConfig:
    trips: int = 0             # 0: as the scenario says
    heartbeat_hz: float = 5.0
    fix_sd_mm: int = 3         # one-sigma of a camera fix, sent in FIX
    map: str = ""              # a learned map to load at the start and save at the end


@dataclasses.dataclass(frozen=True)
class Config:
    arena: ArenaConfig = ArenaConfig()
    link: LinkConfig = LinkConfig()
    camera: CameraConfig = CameraConfig()
    sonar: SonarConfig = SonarConfig()
    mission: MissionConfig = MissionConfig()
    vision: Any = None    # VisionConfig
    planner: Any = None   # PlannerConfig
    rover: dict = dataclasses.field(default_factory=dict)  # Param -> int

    def rover_params(self) -> list[tuple[mg.Param, int]]:
        return sorted(self.rover.items())


def _typed(section: str, key: str, value: Any, want: type, where: str) -> Any:
    if want is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if want is str and isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, want) or isinstance(value, bool) and want is not bool:
        raise ConfigError(f"{where}[{section}] {key} = {value!r} should be {want.__name__}")
    return value


def _section(cls, section: str, table: Any, where: str, checks: dict | None = None):
    if not isinstance(table, dict):
        raise ConfigError(f"{where}[{section}] should be a table")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in table.items():
        if key not in fields:
            raise ConfigError(f"{where}[{section}] has no key {key!r} (known: {', '.join(fields)})")
        want = type(getattr(cls(), key))
        kwargs[key] = _typed(section, key, value, want, where)
        if checks and key in checks and not checks[key](kwargs[key]):
            raise ConfigError(f"{where}[{section}] {key} = {value!r} is out of range")
    return cls(**kwargs)


def config_from_dict(data: dict, where: str = "") -> Config:
    """Build and validate a Config from a parsed TOML document; `where` prefixes messages."""
    from .planning import PlannerConfig
    from .vision.config import VisionConfig

    positive = lambda v: v > 0  # noqa: E731
    known = {"arena", "link", "camera", "vision", "planner", "sonar", "mission", "rover"}
    for name in data:
        if name not in known:
            raise ConfigError(f"{where}unknown section [{name}] (known: {', '.join(sorted(known))})")
    arena = _section(ArenaConfig, "arena", data.get("arena", {}), where,
                     {"width_m": positive, "height_m": positive})
    link = _section(LinkConfig, "link", data.get("link", {}), where,
                    {"baud": lambda v: v in (9600, 19200, 38400, 57600, 115200)})
    camera = _section(CameraConfig, "camera", data.get("camera", {}), where, {"fps": positive})
    sonar = _section(SonarConfig, "sonar", data.get("sonar", {}), where, {"offset_m": lambda v: 0 <= v < 1})
    mission = _section(MissionConfig, "mission", data.get("mission", {}), where,
                       {"trips": lambda v: 0 <= v <= 1000, "heartbeat_hz": positive,
                        "fix_sd_mm": lambda v: 1 <= v <= 255})
    try:
        vision = VisionConfig.from_dict(data.get("vision", {}))
    except ValueError as exc:
        raise ConfigError(f"{where}[vision] {exc}") from None
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
    return Config(arena, link, camera, sonar, mission, vision, planner, rover)


def load_config(path: str | Path | None) -> Config:
    """Read a TOML configuration file (None: every default)."""
    if path is None:
        return config_from_dict({})
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"configuration file {path} not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return config_from_dict(data, where=f"{path}: ")
