"""Camera frames as the run log keeps them: JPEG, at one quality (the writer's and the simulator's
camera process's; this module needs only OpenCV, so the camera process need not load the writer)."""

from __future__ import annotations

import numpy as np

#: JPEG quality of the kept images.
JPEG_QUALITY = 75


def encode_jpeg(frame_bgr: np.ndarray) -> bytes | None:
    """A camera frame as the log keeps it (JPEG_QUALITY); None when OpenCV cannot encode it."""
    import cv2

    ok, jpeg = cv2.imencode(".jpg", frame_bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return jpeg.tobytes() if ok else None
