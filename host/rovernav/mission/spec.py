"""What a host's Mission is made from, in plain values: one place that builds it.

`rovernav sim`, `rovernav run` and `rovernav replay` all make their Mission through
`MissionSpec.build()`. The spec holds nothing but numbers, strings and the scenario's TOML, so a
run log keeps it whole (`to_json`) and a replay builds the very same mission from the log
(`from_json`), with any planner setting changed (`with_planner`) to see what that would have
decided differently.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..config import MAX_FIX_HZ, min_fix_hz
from ..link import messages_gen as mg
from ..planning import OccupancyGrid, PlannerConfig
from .core import Mission
from .legs import Deadlines, legs_per_trip
from .strategies import make_strategy

SPEC_FORMAT = "rovernav.mission-spec"
SPEC_VERSION = 1


@dataclasses.dataclass(frozen=True)
class MissionSpec:
    """The inputs of Mission's constructor that decide what the host does (not the link, the
    clock or the files it keeps)."""

    start_xy: tuple[float, float]
    target_xy: tuple[float, float]
    legs: int
    arena_w_m: float
    arena_h_m: float
    scenario_toml: str | None  # the known obstacles come from it; None: an empty arena
    planner: dict[str, float]  # PlannerConfig's fields
    rover_params: tuple[tuple[int, int], ...]  # (Param, value) the caller adds to the planner's and the strategy's
    fix_sd_mm: int = 3
    heartbeat_hz: float = 5.0
    fix_hz: float = 0.0  # 0: a FIX for every frame that sees the rover
    host_replan: bool = True
    strategy: str = "rovernav"
    planner_name: str = "astar"
    host_boot_id: int = 0

    # ------------------------------------------------------------ making one

    @classmethod
    def for_run(
        cls,
        scenario,
        cfg,
        *,
        strategy: str = "rovernav",
        host_replan: bool = True,
        rover_params: list | None = None,
        start_xy: tuple[float, float] | None = None,
        target_xy: tuple[float, float] | None = None,
        host_boot_id: int = 0,
    ) -> MissionSpec:
        """The spec of a run over `scenario` (None: an empty arena of the configuration's size,
        with `start_xy` and `target_xy` given, e.g. from the camera) under configuration `cfg`.
        Legs: the scenario's trips (or [mission] trips), two a trip out and back."""
        from ..scenario import scenario_toml

        trips = cfg.mission.trips or (scenario.mission.trips if scenario is not None else 1)
        per_trip = legs_per_trip(scenario.mission.kind) if scenario is not None else 1
        if scenario is not None:
            start_xy = start_xy or (scenario.start.x_m, scenario.start.y_m)
            target_xy = target_xy or (scenario.target.x_m, scenario.target.y_m)
            arena = (scenario.arena.width_m, scenario.arena.height_m)
        else:
            if start_xy is None or target_xy is None:
                raise ValueError("a mission with no scenario needs its start and target")
            arena = (cfg.arena.width_m, cfg.arena.height_m)
        params = cfg.rover_params() if rover_params is None else rover_params
        return cls(
            start_xy=(float(start_xy[0]), float(start_xy[1])),
            target_xy=(float(target_xy[0]), float(target_xy[1])),
            legs=trips * per_trip,
            arena_w_m=float(arena[0]),
            arena_h_m=float(arena[1]),
            scenario_toml=None if scenario is None else scenario_toml(scenario),
            planner=(cfg.planner or PlannerConfig()).to_dict(),
            rover_params=tuple((int(p), int(v)) for p, v in params),
            fix_sd_mm=cfg.mission.fix_sd_mm,
            heartbeat_hz=cfg.mission.heartbeat_hz,
            fix_hz=cfg.mission.fix_hz,
            host_replan=host_replan,
            strategy=strategy,
            planner_name=cfg.mission.planner,
            host_boot_id=host_boot_id & 0xFFFFFFFF,
        )

    def with_planner(self, **changes: float) -> MissionSpec:
        """The same mission with planner settings changed (ValueError names a bad one)."""
        planner = PlannerConfig.from_dict({**self.planner, **changes})
        return dataclasses.replace(self, planner=planner.to_dict())

    def with_boot_id(self, host_boot_id: int) -> MissionSpec:
        return dataclasses.replace(self, host_boot_id=host_boot_id & 0xFFFFFFFF)

    # ------------------------------------------------------------ using one

    def grid(self) -> OccupancyGrid:
        """The planner's grid: the arena with the scenario's known obstacles."""
        config = PlannerConfig.from_dict(self.planner)
        if self.scenario_toml is None:
            return OccupancyGrid(self.arena_w_m, self.arena_h_m, config)
        from ..scenario import parse_scenario

        return OccupancyGrid.from_scenario(parse_scenario(self.scenario_toml, "<run log scenario>"), config)

    def build(
        self,
        link,
        *,
        on_event: Callable[[float, str], None] | None = None,
        map_file: str | Path | None = None,
        state_file: str | Path | None = None,
        deadlines: Deadlines = Deadlines(),
        recorder=None,
    ) -> Mission:
        """The Mission this spec describes, over `link`."""
        return Mission(
            link,
            self.grid(),
            self.start_xy,
            self.target_xy,
            legs=self.legs,
            rover_params=[(mg.Param(p), v) for p, v in self.rover_params],
            planner=self.planner_name,
            fix_sd_mm=self.fix_sd_mm,
            heartbeat_hz=self.heartbeat_hz,
            fix_hz=self.fix_hz,
            host_replan=self.host_replan,
            on_event=on_event,
            map_file=map_file,
            state_file=state_file,
            strategy=make_strategy(self.strategy),
            deadlines=deadlines,
            host_boot_id=self.host_boot_id,
            recorder=recorder,
        )

    # ------------------------------------------------------------ files

    def to_json(self) -> str:
        data: dict[str, Any] = {"format": SPEC_FORMAT, "version": SPEC_VERSION, **dataclasses.asdict(self)}
        return json.dumps(data, allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> MissionSpec:
        """A spec from to_json()'s text; ValueError when it is not one."""
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise ValueError(f"the mission spec is not JSON: {exc}") from None
        if not isinstance(data, dict) or data.get("format") != SPEC_FORMAT:
            raise ValueError("not a rovernav mission spec")
        if data.get("version") != SPEC_VERSION:
            raise ValueError(f"mission spec version {data.get('version')!r}; this rovernav reads {SPEC_VERSION}")
        fields = {f.name for f in dataclasses.fields(cls)}
        # A field added since version 1 is read with its default from a log written before it.
        for name, default in _ADDED_SINCE_VERSION_1.items():
            data.setdefault(name, default)
        missing = fields - set(data)
        if missing:
            raise ValueError(f"the mission spec lacks {', '.join(sorted(missing))}")
        values = {k: data[k] for k in fields}
        try:
            values["start_xy"] = tuple(float(v) for v in values["start_xy"])
            values["target_xy"] = tuple(float(v) for v in values["target_xy"])
            values["rover_params"] = tuple((int(p), int(v)) for p, v in values["rover_params"])
            PlannerConfig.from_dict(values["planner"])
            make_strategy(values["strategy"])
            values["fix_hz"] = float(values["fix_hz"])
            low = min_fix_hz(dict(values["rover_params"]).get(int(mg.Param.FIX_TIMEOUT_MS), 500))
            if values["fix_hz"] != 0.0 and not low <= values["fix_hz"] <= MAX_FIX_HZ:
                raise ValueError(f"fix_hz {values['fix_hz']:g}: 0, or {low:g} to {MAX_FIX_HZ:g}")
        except (TypeError, ValueError) as exc:
            raise ValueError(f"the mission spec has a bad value: {exc}") from None
        return cls(**values)


#: Fields a spec of version 1 may lack (a log written before them), with the value that run had.
_ADDED_SINCE_VERSION_1 = {"fix_hz": 0.0}

#: The files a host keeps in its working folder, so that a restarted host takes up the mission.
MAP_FILE = "learned-map.json"
STATE_FILE = "mission-state.json"


def start_host(
    spec: MissionSpec, link, workdir: Path, *, on_event: Callable[[float, str], None] | None = None, recorder=None
) -> Mission:
    """A host process starting on `spec`, keeping its learned map and the legs it has done in
    `workdir`: a host that restarts there reloads both (the simulator's --host-restart, and
    `rovernav replay` of such a run, go through here)."""
    map_file = Path(workdir) / MAP_FILE
    mission = spec.build(
        link, on_event=on_event, map_file=map_file, state_file=Path(workdir) / STATE_FILE, recorder=recorder
    )
    if map_file.exists():  # a restarted host: its learned map survived on disk
        mission.load_map(map_file)
    mission.restore_state()
    return mission
