"""Several rovers in one frame, told apart by their ArUco tags (issue 30's "who is who").

    locator = FleetLocator(VisionConfig(markers="aruco"), 2.36, 1.75, {1: 1, 2: 3, 3: 4})
    seen = locator.locate(frame, t_s)
    seen.rovers[2]      # RoverPose of rover 2, or None
    seen.reasons[2]     # why not: "rover 2 tag (id 3) not found", a jump, a doubled tag

Each rover carries its own tag (`{rover id: tag id}`, every id different from the others' and the
target's), so two rovers cannot be confused with each other: a fix is a tag of that id, one of it,
of the right size, not further from the rover's last fix than its speed allows. A rover that is not
found is said by its id and why, and the others are still located. Each rover has its own jump
check, as the single-rover `Locator` has for its one rover. The whole frame is searched each time
(one ArUco pass finds every tag; about 1.5 ms for 640 x 480).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..vehicle_gen import DEFAULT_ARENA_HEIGHT_MM, DEFAULT_ARENA_WIDTH_MM
from .config import VisionConfig
from .locator import Locator, RoverPose, TargetPosition, tag_corners, tag_pose


def fleet_tags(rovers: int, rover_tag: int = 1, target_tag: int = 2) -> dict[int, int]:
    """Each rover's ArUco tag id: rover 1 has the lone rover's ([vision.aruco] rover_id), rovers
    2, 3, ... the next ids after it that are not the target's (with the defaults: 1, 3, 4, 5)."""
    tags, tag = {1: rover_tag}, rover_tag
    for k in range(2, rovers + 1):
        tag += 1
        while tag == target_tag:
            tag += 1
        tags[k] = tag
    return tags


@dataclass(frozen=True)
class FleetDetection:
    """What one frame showed: each rover's pose (None when not found) and, for those, why not;
    the target as the single-rover Locator gives it; pixels and areas by label ("rover 2", "target")."""

    rovers: dict[int, RoverPose | None]
    reasons: dict[int, str]
    target: TargetPosition | None
    target_reason: str | None = None
    pixels: dict[str, tuple[float, float]] = field(default_factory=dict)
    areas_px: dict[str, float] = field(default_factory=dict)
    t_s: float | None = None

    @property
    def lost(self) -> list[int]:
        """The rovers this frame did not locate, by id."""
        return sorted(r for r, pose in self.rovers.items() if pose is None)


class FleetLocator(Locator):
    """Locates every rover of a fleet, each by its own ArUco tag (see the module's doc). A Locator
    for the camera's calibration and the jump check; its own `locate`."""

    def __init__(
        self,
        config: VisionConfig,
        arena_w_m: float = DEFAULT_ARENA_WIDTH_MM / 1000.0,
        arena_h_m: float = DEFAULT_ARENA_HEIGHT_MM / 1000.0,
        tag_ids: Mapping[int, int] | None = None,
    ):
        if config.markers != "aruco":
            raise ValueError(f"a fleet is told apart by ArUco tags: [vision] markers = 'aruco', not {config.markers!r}")
        super().__init__(config, arena_w_m, arena_h_m)
        tags = {1: config.aruco.rover_id} if tag_ids is None else dict(tag_ids)
        if not tags:
            raise ValueError("a fleet of no rovers")
        for rover, tag in tags.items():
            if not isinstance(tag, int) or isinstance(tag, bool) or not 0 <= tag < self._aruco.dictionary_size:
                raise ValueError(
                    f"rover {rover}: tag id {tag!r} is not one of {config.aruco.dictionary}'s "
                    f"(0 to {self._aruco.dictionary_size - 1})"
                )
        if len(set(tags.values())) != len(tags):
            raise ValueError(f"two rovers with one tag id: {tags}")
        if config.aruco.target_id in tags.values():
            raise ValueError(f"a rover's tag id is the target's ({config.aruco.target_id})")
        self.tag_ids = tags
        self._fleet_last: dict[int, tuple[float, float, float | None]] = {}  # rover -> its last fix

    def reset(self, rover: int | None = None) -> None:
        """Forget one rover's last fix (moved by hand, say), or every rover's."""
        if rover is None:
            self._fleet_last = {}
        else:
            self._fleet_last.pop(rover, None)

    def locate(self, frame_bgr: np.ndarray, t_s: float | None = None) -> FleetDetection:  # type: ignore[override]
        """Every rover and the target in a BGR uint8 frame taken at t_s seconds (None: no jump check)."""
        if frame_bgr.ndim != 3 or frame_bgr.shape[2] != 3 or frame_bgr.dtype != np.uint8:
            raise ValueError(f"frame: expected a BGR uint8 image (H x W x 3), got {frame_bgr.dtype} {frame_bgr.shape}")
        cal = self.calibration_for(frame_bgr.shape[1], frame_bgr.shape[0])
        acfg = self.config.aruco
        assert self._aruco is not None
        tags = self._aruco.find_gray(cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY))
        pixels: dict[str, tuple[float, float]] = {}
        areas: dict[str, float] = {}
        target = None
        t_corners, target_reason = tag_corners(
            tags.get(acfg.target_id, []), acfg.target_id, "target", cal, acfg, pixels, areas
        )
        if t_corners is not None:
            c = t_corners.mean(axis=0)
            target = TargetPosition(float(c[0]), float(c[1]))
        rovers: dict[int, RoverPose | None] = {}
        reasons: dict[int, str] = {}
        for rover, tag_id in self.tag_ids.items():
            label = f"rover {rover}"
            corners, reason = tag_corners(tags.get(tag_id, []), tag_id, label, cal, acfg, pixels, areas)
            pose = None
            if corners is not None:
                pose = tag_pose(corners)
                jump = self._jump_problem(pose.x_m, pose.y_m, t_s, self._fleet_last.get(rover))
                if jump is not None:
                    pose, reason = None, f"{label}: {jump}"
            rovers[rover] = pose
            if pose is None:
                reasons[rover] = reason or f"{label} not found"
            else:
                self._fleet_last[rover] = (pose.x_m, pose.y_m, t_s)
        return FleetDetection(rovers, reasons, target, target_reason, pixels, areas, t_s)
