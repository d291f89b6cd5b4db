"""The colour-marker locator as it was before it was made faster (commit 8c6a53c), kept as the
reference the fast one must agree with bit for bit.

`ReferenceColourMarkers` is `ColourMarkers` with that version's search, step for step, and
`ReferenceLocator` a Locator that uses it and maps pixels to the arena as was done then (always
Calibration._apply). tests/test_vision_identity.py checks that the fast and the reference finders
give equal `BlobSearch`es and the two locators equal `Detection`s on tracking sequences and cold
frames; benchmarks/bench_vision.py times both in the same run. Nothing else uses this module; do
not change it to follow the fast version.
"""

from __future__ import annotations

import copy

import cv2
import numpy as np

from .calibration import Calibration
from .colour_markers import _STRONG_HI, _STRONG_LO, Blob, BlobSearch, ColourMarkers
from .config import VisionConfig
from .locator import Locator


class ReferenceColourMarkers(ColourMarkers):
    """ColourMarkers with the previous implementation of every step of the search."""

    def find(self, frame_bgr: np.ndarray, hints: dict[str, tuple[float, float]] | None = None) -> dict[str, BlobSearch]:
        """Search a BGR uint8 frame for each marker colour.

        hints: where each marker was last seen (pixels). A marker is first looked for in a window
        around its hint, and in the whole frame only if that finds no single blob clear of the
        window's edges: the same answer, a fraction of the work when the markers move little
        between frames.
        """
        out: dict[str, BlobSearch] = {}
        rest = []
        for name in self.NAMES:
            hint = (hints or {}).get(name)
            found = self._find_in_window(name, frame_bgr, hint) if hint is not None else None
            if found is not None:
                out[name] = found
            else:
                rest.append(name)
        if rest:
            s = self.config.downscale
            h, w = frame_bgr.shape[:2]
            small = frame_bgr if s == 1 else cv2.resize(frame_bgr, (w // s, h // s), interpolation=cv2.INTER_AREA)
            hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
            for name in rest:
                out[name] = self._choose(
                    name, frame_bgr, self._mask(name, hsv), self.config.min_blob_area_px / (s * s), s
                )
        return out

    def _mask(self, name: str, hsv: np.ndarray) -> np.ndarray:
        lo, hi = self.ranges[name]
        mask = cv2.inRange(hsv, lo, hi)
        if self.config.open_kernel_px > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        if self.config.close_kernel_px > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)
        return mask

    def _find_in_window(self, name: str, frame: np.ndarray, hint: tuple[float, float]) -> BlobSearch | None:
        s = self.config.downscale
        half = self.WINDOW_HALF_PX[name]
        fh, fw = frame.shape[:2]
        x0, y0 = max(0, int(hint[0]) - half), max(0, int(hint[1]) - half)
        x0, y0 = x0 - x0 % s, y0 - y0 % s
        x1, y1 = min(fw, x0 + 2 * half), min(fh, y0 + 2 * half)
        if x1 - x0 < 4 * s or y1 - y0 < 4 * s:
            return None
        win = frame[y0:y1, x0:x1]
        small = win if s == 1 else cv2.resize(win, ((x1 - x0) // s, (y1 - y0) // s), interpolation=cv2.INTER_AREA)
        mask = self._mask(name, cv2.cvtColor(small, cv2.COLOR_BGR2HSV))
        found = self._choose(
            name, frame, mask, self.config.min_blob_area_px / (s * s), s, origin=(x0, y0), edge_ok=False
        )
        return found if found.blob is not None else None

    def _choose(
        self,
        name: str,
        frame: np.ndarray,
        mask: np.ndarray,
        min_area_small: float,
        s: int,
        origin: tuple[int, int] = (0, 0),
        edge_ok: bool = True,
    ) -> BlobSearch:
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        blobs = []
        mh, mw = mask.shape[:2]
        for c in contours:
            x, y, w, h = cv2.boundingRect(c)
            area = cv2.countNonZero(mask[y : y + h, x : x + w])
            if area >= min_area_small:
                if not edge_ok and (x == 0 or y == 0 or x + w >= mw or y + h >= mh):
                    return BlobSearch(None, "at the window's edge", 0)  # let the whole frame decide
                blobs.append((area, x, y, w, h))
        if not blobs:
            return BlobSearch(None, "not found", 0)
        blobs.sort(reverse=True)
        big = blobs[0][0]
        k = sum(1 for b in blobs if b[0] >= self.config.doubled_area_ratio * big)
        if k > 1:
            return BlobSearch(None, "two candidate" if k == 2 else f"{k} candidate", k)
        area, x, y, w, h = blobs[0]
        blob = self._refine(name, frame, origin[0] + x * s, origin[1] + y * s, w * s, h * s, s)
        if blob is None:
            return BlobSearch(None, "not found", 0)
        return BlobSearch(blob, None, 1)

    def _refine(self, name: str, frame: np.ndarray, x: int, y: int, w: int, h: int, s: int) -> Blob | None:
        """Chroma-weighted centroid in the full-resolution window around a blob's bounding box."""
        pad = s + 3
        fh, fw = frame.shape[:2]
        x0, y0 = max(x - pad, 0), max(y - pad, 0)
        x1, y1 = min(x + w + pad, fw), min(y + h + pad, fh)
        win = frame[y0:y1, x0:x1]
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        lo, hi = self.ranges[name]
        strict = cv2.inRange(hsv, lo, hi)
        if not cv2.countNonZero(strict):
            return None
        core = cv2.erode(strict, self._kernel3)
        if not cv2.countNonZero(core):
            core = strict
        # Where to weigh: the marker's pixels and a ring one pixel wide around them, which holds its
        # faint edge pixels. Weights are not clipped at zero, so the background's noise in the ring
        # averages out instead of pulling the centroid outwards; but pixels clearly of another colour
        # (say the yellow target under the orange front marker, whose chroma points much the same
        # way) are left out.
        support = cv2.dilate(strict, self._kernel3)
        foreign = cv2.bitwise_and(
            cv2.inRange(hsv, _STRONG_LO, _STRONG_HI),
            cv2.bitwise_not(cv2.inRange(hsv, self._gate_lo[name], self._gate_hi[name])),
        )
        use = cv2.bitwise_and(support, cv2.bitwise_not(foreign))
        winf = win.astype(np.float32)
        chroma = winf - winf.mean(axis=2, keepdims=True)
        ref = chroma[core > 0].mean(axis=0)
        ref_sq = float(ref @ ref)
        if ref_sq < 1e-6:
            return None
        weight = (chroma @ (ref / ref_sq)) * (use > 0)
        total = float(weight.sum())
        if total <= 0:
            return None
        u = float(weight.sum(axis=0) @ np.arange(x0, x1, dtype=np.float32)) / total
        v = float(weight.sum(axis=1) @ np.arange(y0, y1, dtype=np.float32)) / total
        return Blob(u, v, total)


class ReferenceLocator(Locator):
    """A Locator as it was before: colour markers found by ReferenceColourMarkers, and pixels
    mapped to the arena always through Calibration._apply (no shortcut for one point)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self._colour is not None:
            self._colour = ReferenceColourMarkers(self.config)
        self._plain: dict[int, Calibration] = {}

    def calibration_for(self, width_px: int, height_px: int) -> Calibration:
        cal = super().calibration_for(width_px, height_px)
        if id(cal) not in self._plain:
            plain = copy.copy(cal)
            plain._axis_scales = None
            self._plain[id(cal)] = plain
        return self._plain[id(cal)]


def reference_locator(
    config: VisionConfig | None = None, arena_w_m: float | None = None, arena_h_m: float | None = None
) -> Locator:
    """A ReferenceLocator (arena size as for Locator: the defaults when not given)."""
    kw = {k: v for k, v in (("arena_w_m", arena_w_m), ("arena_h_m", arena_h_m)) if v is not None}
    return ReferenceLocator(config, **kw)
