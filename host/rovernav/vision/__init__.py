"""Find the rover and the target in overhead camera frames.

    from rovernav.vision import Locator, VisionConfig
    locator = Locator(VisionConfig(), arena_w_m=2.36, arena_h_m=1.75)
    detection = locator.locate(frame_bgr, t_s=now_s)

Modules: config (VisionConfig, from a TOML [vision] table), calibration (pixels <-> arena metres),
colour_markers / aruco_markers (finding markers in a frame), locator (Locator, Detection),
cli (the `rovernav locate IMAGE` command).
"""

from .calibration import Calibration, heading_deg
from .config import VisionConfig
from .locator import Detection, Locator, RoverPose, TargetPosition

__all__ = ["Calibration", "Detection", "Locator", "RoverPose", "TargetPosition", "VisionConfig", "heading_deg"]
