"""Find the rover and the target in overhead camera frames."""

from .config import VisionConfig
from .locator import Detection, Locator

__all__ = ["Detection", "Locator", "VisionConfig"]
