"""Coloured square markers: find each colour's blob and its sub-pixel centroid.

Two passes, for speed and precision:
1. Find: on a copy `downscale` times smaller (INTER_AREA, which also averages the noise), HSV
   threshold with the configured range, morphological opening (removes specks) and closing (fills
   holes), then the connected blobs (as outer contours: on these sparse masks cv2.findContours
   takes a tenth of the time of connectedComponentsWithStats). Blobs smaller than
   min_blob_area_px are noise; a second blob at least doubled_area_ratio of the largest makes the
   colour ambiguous.
2. Refine: in a small full-resolution window around the chosen blob, weigh each pixel by how much
   of the marker's colour it holds and take the weighted centroid. The weight is the pixel's
   chroma (its colour minus its grey level) projected on the marker's own chroma, measured from the
   blob's core: a pixel that is 30 % marker over a grey or dark background weighs 0.3 (the weights
   are linear in the pixel's colour, never thresholded or clipped, which would bias them). So an edge
   that moves by a tenth of a pixel moves the centroid with it; nothing is ever rounded to whole
   pixels (the seed's int() centroids made a still rover's heading jump by 2.5 degrees).
   The backgrounds the markers sit on (floor, dark rover body) must be near-neutral for this.

While tracking, each marker is first looked for in a window around where it was in the last frame
(`find`'s hints). The code takes shortcuts there that give the same values bit for bit as the
plain version, kept as ReferenceColourMarkers in colour_markers_reference.py, which
tests/test_vision_identity.py runs beside this one: the opening and closing on a crop of the mask,
colour conversions on strips 32k pixels wide cut to the window, numpy's means without their
wrappers. Each shortcut says why it changes no value.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .config import VisionConfig

# Hue tolerance (OpenCV units) beyond the marker's range for its edge pixels, whose hue is noisier.
_HUE_MARGIN = 4
# "Clearly coloured": saturated and bright enough for the hue to mean something (HSV bounds).
_STRONG_LO = np.array([0, 60, 60], np.uint8)
_STRONG_HI = np.array([179, 255, 255], np.uint8)
_THREE = np.float32(3)
_ONES_1X3 = np.ones((1, 3), np.float32)  # cv2.transform: the sum of a pixel's channels


@dataclass(frozen=True)
class Blob:
    """A marker found in the frame: centroid in full-resolution pixels, area in pixels
    (sum of the weights: the marker's area, sub-pixel)."""

    u_px: float
    v_px: float
    area_px: float


@dataclass(frozen=True)
class BlobSearch:
    """The outcome of looking for one colour: `blob` when exactly one plausible blob was found,
    else `problem`: "not found" or "two candidate" (or "3 candidate", ...)."""

    blob: Blob | None
    problem: str | None = None
    candidates: int = 0


def hue_name(lower_h: int, upper_h: int) -> str:
    """A colour word for an OpenCV hue range (H 0-179), for messages."""
    h = (lower_h + upper_h) / 2 * 2  # degrees
    for limit, name in (
        (15, "red"),
        (48, "orange"),
        (70, "yellow"),
        (160, "green"),
        (200, "cyan"),
        (260, "blue"),
        (300, "purple"),
        (340, "magenta"),
        (361, "red"),
    ):
        if h < limit:
            return name
    return "red"


class ColourMarkers:
    """Finds the target, rover-front and rover-back colour markers of a VisionConfig."""

    NAMES = ("target", "rover_front", "rover_back")

    def __init__(self, config: VisionConfig):
        self.config = config
        self.ranges = {
            name: (np.array(getattr(config.hsv, name)[0], np.uint8), np.array(getattr(config.hsv, name)[1], np.uint8))
            for name in self.NAMES
        }
        self.colour_names = {name: hue_name(int(lo[0]), int(hi[0])) for name, (lo, hi) in self.ranges.items()}
        self._open = cv2.getStructuringElement(cv2.MORPH_RECT, (config.open_kernel_px,) * 2)
        self._close = cv2.getStructuringElement(cv2.MORPH_RECT, (config.close_kernel_px,) * 2)
        self._kernel3 = np.ones((3, 3), np.uint8)
        # How far beyond the thresholded mask's non-zero pixels the opening and closing can reach or
        # look (a rect kernel of k pixels reaches k // 2 either way): the opening's dilation, the
        # closing's dilation, and its erosion looking one reach further (see _mask).
        k_open = config.open_kernel_px // 2 if config.open_kernel_px > 1 else 0
        k_close = config.close_kernel_px // 2 if config.close_kernel_px > 1 else 0
        self._margin = k_open + 2 * k_close + 1
        self._gate_lo = {
            n: np.array([max(int(lo[0]) - _HUE_MARGIN, 0), 0, 0], np.uint8) for n, (lo, hi) in self.ranges.items()
        }
        self._gate_hi = {
            n: np.array([min(int(hi[0]) + _HUE_MARGIN, 179), 255, 255], np.uint8) for n, (lo, hi) in self.ranges.items()
        }

    # Half-sizes (full-resolution pixels) of the windows searched around a marker's last place.
    WINDOW_HALF_PX = {"target": 32, "rover_front": 64, "rover_back": 64}

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
                    name, frame_bgr, hsv.shape[:2], self._mask(name, hsv), self.config.min_blob_area_px / (s * s), s
                )
        return out

    def _mask(self, name: str, hsv: np.ndarray) -> tuple[np.ndarray | None, int, int]:
        """The colour's mask, opened and closed, as (crop, x, y): the part of it where it can be
        non-zero, at (x, y) in the whole; (None, 0, 0) when it is zero everywhere.

        The thresholded mask is mostly zero (a marker or three, a speck or two), so the opening and
        the closing run only on a crop of it: its non-zero pixels' bounding box grown by `_margin`.
        That is the whole mask's result, cut out: erode and dilate ignore what lies beyond a
        crop's edge, where the whole mask has zeros; to a dilation zeros are nothing either, and an
        erosion can only tell them apart next to a pixel that is non-zero, which at every step the
        margin keeps more than a kernel's reach inside the crop. Outside the crop the result is zero.
        """
        lo, hi = self.ranges[name]
        mask = cv2.inRange(hsv, lo, hi)
        x, y, w, h = cv2.boundingRect(mask)
        if w == 0:
            return None, 0, 0
        m = self._margin
        mh, mw = mask.shape[:2]
        x0, y0 = max(x - m, 0), max(y - m, 0)
        crop = mask[y0 : min(y + h + m, mh), x0 : min(x + w + m, mw)]
        if self.config.open_kernel_px > 1:
            crop = cv2.morphologyEx(crop, cv2.MORPH_OPEN, self._open)
        if self.config.close_kernel_px > 1:
            crop = cv2.morphologyEx(crop, cv2.MORPH_CLOSE, self._close)
        return crop, x0, y0

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
        hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
        found = self._choose(
            name,
            frame,
            hsv.shape[:2],
            self._mask(name, hsv),
            self.config.min_blob_area_px / (s * s),
            s,
            (x0, y0),
            False,
        )
        return found if found.blob is not None else None

    def _choose(
        self,
        name: str,
        frame: np.ndarray,
        mask_hw: tuple[int, int],
        cleaned: tuple[np.ndarray | None, int, int],
        min_area_small: float,
        s: int,
        origin: tuple[int, int] = (0, 0),
        edge_ok: bool = True,
    ) -> BlobSearch:
        """The one plausible blob of a mask of mask_hw pixels, given as `_mask` crops it."""
        mask, cx, cy = cleaned
        if mask is None:
            return BlobSearch(None, "not found", 0)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        blobs = []
        mh, mw = mask_hw
        for c in contours:
            x, y, w, h = cv2.boundingRect(c)
            area = cv2.countNonZero(mask[y : y + h, x : x + w])
            x, y = x + cx, y + cy
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
        # The colour masks are per pixel: they are made on a strip of whole multiples of 32 pixels
        # holding the window, where OpenCV's HSV conversion and inRange run at full SIMD width
        # (several times faster than on a window some 26 pixels wide, whose rows end in scalar
        # code), then cut to the window. The two paths convert every BGR colour alike (a test goes
        # through all 2^24); the erosion and dilation run on the window's own extent (a view: they
        # read nothing beyond it), as before.
        wide = -(-(x1 - x0) // 32) * 32
        sx0 = min(x0, fw - wide) if wide <= fw else x0
        sx1 = max(sx0 + wide, x1)
        hsv = cv2.cvtColor(frame[y0:y1, sx0:sx1], cv2.COLOR_BGR2HSV)
        cut = slice(x0 - sx0, x1 - sx0)
        lo, hi = self.ranges[name]
        strict = cv2.inRange(hsv, lo, hi)[:, cut]
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
        # use = support and not foreign, foreign = strong and not gate: on 0/255 masks a saturating
        # a - b is a and not b.
        foreign = cv2.subtract(
            cv2.inRange(hsv, _STRONG_LO, _STRONG_HI), cv2.inRange(hsv, self._gate_lo[name], self._gate_hi[name])
        )
        use = cv2.subtract(support, foreign[:, cut])
        winf = win.astype(np.float32)
        # chroma and ref are what winf - winf.mean(axis=2, keepdims=True) and chroma[core > 0].mean(axis=0)
        # give, bit for bit, with less overhead: numpy's mean is a float32 sum (here of three integers,
        # exact in any order) divided by intp(n) in float64 and rounded to float32, which equals the
        # float32 division (double rounding is innocuous for a quotient: 53 >= 2 * 24 + 2 bits).
        grey = cv2.transform(winf, _ONES_1X3)
        grey /= _THREE
        chroma = cv2.subtract(winf, cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))  # a float32 difference, as numpy's
        in_core = chroma.reshape(-1, 3).compress(core.reshape(-1), axis=0)  # chroma[core > 0], rows in order
        ref = np.add.reduce(in_core, axis=0)
        ref /= np.float32(len(in_core))
        ref_sq = float(ref @ ref)
        if ref_sq < 1e-6:
            return None
        weight = (chroma @ (ref / ref_sq)) * (use > 0)
        # np.add.reduce is what weight.sum() calls, without the Python wrapper.
        total = float(np.add.reduce(weight, axis=None))
        if total <= 0:
            return None
        u = float(np.add.reduce(weight, axis=0) @ np.arange(x0, x1, dtype=np.float32)) / total
        v = float(np.add.reduce(weight, axis=1) @ np.arange(y0, y1, dtype=np.float32)) / total
        return Blob(u, v, total)
