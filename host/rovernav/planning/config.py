"""The planner's settings, in one frozen dataclass."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..link.messages_gen import PARAMS, Param


def geometry_m(param: Param) -> float:
    """A length of the rover's geometry [m], from its one definition (protocol/messages.toml)."""
    return PARAMS[param].default / 1000.0


@dataclasses.dataclass(frozen=True)
class PlannerConfig:
    """Grid, inflation, sonar and potential-field settings. Lengths in metres, angles in degrees.

    The inflation (`inflation_m`) is the robot radius plus the sonar placement margin: the
    seed's rover is 0.15 × 0.21 m, and its sonar put an obstacle up to 0.05 m from where it was
    (section 5.4), so the planner keeps the rover's centre that far from every obstacle.
    """

    resolution_m: float = 0.03  # side of a grid cell (the seed's grid_size)
    robot_radius_m: float = geometry_m(Param.ROBOT_RADIUS_MM)  # the seed's robot_radius (0.12)
    sonar_margin_m: float = geometry_m(Param.SONAR_MARGIN_MM)  # the sonar's placement error, added to the radius
    sonar_offset_m: float = geometry_m(Param.SONAR_OFFSET_MM)  # the sonar sits this far ahead of the rover's centre
    sonar_cone_deg: float = (
        PARAMS[Param.SONAR_CONE_CDEG].default / 100.0
    )  # HC-SR04 beam: an echo may come from anywhere on it
    # The potential field (see planning.potential): U = k_att·d + k_rep·((c0 − c)/c0)² within c0.
    # With k_att = 1, Table 4.2 holds (trapped by the large obstacles, through the small ones)
    # for k_rep from 0.04 to 0.11 and c0 from 0.02 to 0.25 m, from starts moved by up to
    # 6 cm; the defaults sit in the middle (tests/test_planning_paths.py checks a spread of them).
    potential_attractive_gain: float = 1.0  # k_att [1/m]: U grows by this per metre from the target
    potential_repulsive_gain: float = 0.07  # k_rep: the repulsion at the rover body's edge
    potential_influence_m: float = 0.1  # c0: clearance beyond the robot radius where repulsion starts

    _POSITIVE = ("resolution_m", "sonar_cone_deg", "potential_attractive_gain", "potential_influence_m")
    _NON_NEGATIVE = ("robot_radius_m", "sonar_margin_m", "sonar_offset_m", "potential_repulsive_gain")

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"planner config: {f.name} must be a finite number, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        for name in self._POSITIVE:
            if getattr(self, name) <= 0:
                raise ValueError(f"planner config: {name} must be > 0, got {getattr(self, name)!r}")
        for name in self._NON_NEGATIVE:
            if getattr(self, name) < 0:
                raise ValueError(f"planner config: {name} must be ≥ 0, got {getattr(self, name)!r}")
        cone = PARAMS[Param.SONAR_CONE_CDEG]  # the rover is sent it: its limits are the parameter's
        if not cone.min / 100 <= self.sonar_cone_deg <= cone.max / 100:
            raise ValueError(
                f"planner config: sonar_cone_deg must be {cone.min / 100:g}-{cone.max / 100:g}, "
                f"got {self.sonar_cone_deg!r}"
            )

    @property
    def inflation_m(self) -> float:
        """How far the rover's centre keeps from any obstacle: robot radius + sonar margin."""
        return self.robot_radius_m + self.sonar_margin_m

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> PlannerConfig:
        """A config from a mapping of field names; unknown names and bad values raise ValueError."""
        names = {f.name for f in dataclasses.fields(cls)}
        for key in values:
            if key not in names:
                raise ValueError(f"planner config: unknown key {key!r} (known: {', '.join(sorted(names))})")
        return cls(**values)

    def to_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)

    def rover_geometry(self) -> list[tuple[Param, int]]:
        """The geometry this planner plans with, as the rover's CONFIG parameters (so that its own
        detours keep the same clearance)."""
        return [
            (Param.ROBOT_RADIUS_MM, round(self.robot_radius_m * 1000)),
            (Param.SONAR_MARGIN_MM, round(self.sonar_margin_m * 1000)),
            (Param.SONAR_OFFSET_MM, round(self.sonar_offset_m * 1000)),
            (Param.SONAR_CONE_CDEG, round(self.sonar_cone_deg * 100)),
        ]

    def replace(self, **changes: Any) -> PlannerConfig:
        return self.from_dict({**self.to_dict(), **changes})
