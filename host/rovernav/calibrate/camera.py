"""The camera's calibration from what it sees: where the arena lies in the frame, and the HSV
ranges of the rover's and the target's colour markers under the light of the room.

    result = calibrate_camera(frames, arena_w_m=2.36, arena_h_m=1.75)
    result.vision(base_config)      # a VisionConfig with the corners and the ranges found

The arena, one of:
- four ArUco corner tags (ids 10, 11, 12, 13 of DICT_4X4_50 by default: bottom-left,
  bottom-right, top-right, top-left), each with its centre `inset_m` in from both walls at its
  corner; their centres give the floor's homography;
- four pixel points the user gives (the arena's corners, in the same order).

The markers, without knowing their colours beforehand: pixels clearly coloured (saturated and
not dark) are grouped into blobs; a blob of a marker's size (from the homography) that is not
grey is a candidate. The rover is the pair of candidates the marker distance apart; which is
the front and which the target is told by their colours: the colour words the user gives
(`--front orange`), else the hues of the configuration's present ranges. The proposed range of
each marker spans the hues its pixels showed in every frame, with a margin, and the saturation
and brightness down to a fraction of the dimmest pixels; ranges that would meet are split
between them. The proposal is then checked the way the mission will use it: the locator, with
the new ranges, must find the rover in every frame, and nothing else.

Every refusal is one line naming what to change: no arena, a frame too dark, a marker cut by
the frame's edge, no rover pair, a colour that was asked for and not seen.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import cv2
import numpy as np

from ..vision.calibration import Calibration
from ..vision.colour_markers import hue_name
from ..vision.config import VisionConfig
from ..vision.marks import COLOUR_BANDS, CORNER_DICTIONARY, CORNER_INSET_M, CORNER_TAG_IDS

MARKER_SIZE_M = 0.05  # the colour squares on the rover (RoverLook.marker_size_m)
TARGET_SIZE_M = 0.06

#: "Clearly coloured": at least this saturation and brightness (OpenCV units, 0-255).
MIN_SATURATION = 90
MIN_VALUE = 40
#: A frame darker than this mean brightness (0-255) is refused: colours are noise there.
MIN_MEAN_VALUE = 35
#: Hue margin added each side of what the marker's pixels showed (OpenCV H units, 0-179).
HUE_MARGIN = 5
#: The lower S and V bounds are this fraction of the dimmest 1 % of the marker's pixels.
SV_FRACTION = 0.6
SV_FLOOR = 40
#: A blob counts as a marker when its area is within these factors of the marker's expected area.
AREA_RANGE = (0.3, 2.5)

ROLES = ("rover_front", "rover_back", "target")


class CalibrationFailed(Exception):
    """Calibration could not be done from these frames; the message says why, in one line."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A clearly coloured blob of a marker's size: its centroid (pixels, arena metres), its area
    (pixels), its median hue (OpenCV H) and its pixels' H, S, V."""

    frame: int
    u_px: float
    v_px: float
    x_m: float
    y_m: float
    area_px: float
    hue: float
    pixels_hsv: np.ndarray


@dataclasses.dataclass
class CameraCalibration:
    corners_px: tuple[tuple[float, float], ...]  # the arena's corners in the frame (BL, BR, TR, TL)
    arena_w_m: float
    arena_h_m: float
    how: str  # "corner tags" or "points given"
    hsv: dict[str, tuple[tuple[int, int, int], tuple[int, int, int]]]
    markers: dict[str, list[Candidate]]  # each role's blob in every frame
    found: int = 0  # frames the locator then found the rover in
    frames: int = 0
    poses: list = dataclasses.field(default_factory=list)  # the locator's RoverPose per frame (None: none)

    @property
    def calibration(self) -> Calibration:
        return Calibration.from_corners(self.corners_px, self.arena_w_m, self.arena_h_m)

    def vision(self, base: VisionConfig | None = None) -> VisionConfig:
        """`base` (default: every default) with colour markers, these ranges and these corners."""
        d = (base or VisionConfig()).to_dict()
        d["markers"] = "colour"
        d["hsv"] = {name: [list(lo), list(hi)] for name, (lo, hi) in self.hsv.items()}
        d["calibration"] = {
            "corners_px": [[round(u, 2), round(v, 2)] for u, v in self.corners_px],
            "width_m": self.arena_w_m,
            "height_m": self.arena_h_m,
        }
        return VisionConfig.from_dict(d)

    def colour_words(self) -> dict[str, str]:
        return {role: hue_name(lo[0], hi[0]) for role, (lo, hi) in self.hsv.items()}


# ---------------------------------------------------------------- the arena


def arena_from_tags(
    frame_bgr: np.ndarray,
    arena_w_m: float,
    arena_h_m: float,
    *,
    tag_ids: tuple[int, int, int, int] = CORNER_TAG_IDS,
    dictionary: str = CORNER_DICTIONARY,
    inset_m: float = CORNER_INSET_M,
) -> tuple[tuple[float, float], ...]:
    """The arena's corners (pixels; bottom-left, bottom-right, top-right, top-left) from its four
    corner tags, or CalibrationFailed naming the tags not seen."""
    gray = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX  # the corners to a tenth of a pixel
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), params)
    seen: dict[int, list[np.ndarray]] = {}
    # A far corner's tag can be a few pixels a cell: looked for again in a copy twice the size.
    for scale in (1, 2):
        img = gray if scale == 1 else cv2.resize(gray, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
        corners, ids, _ = detector.detectMarkers(img)
        seen = {}
        for c, i in zip(corners, [] if ids is None else ids.ravel()):
            # Pixel centres: (u2 + 0.5) / 2 - 0.5 in the frame for u2 in the copy.
            seen.setdefault(int(i), []).append((c.reshape(4, 2).mean(axis=0) + 0.5) / scale - 0.5)
        if all(t in seen for t in tag_ids):
            break
    names = ("bottom-left", "bottom-right", "top-right", "top-left")
    missing = [f"{tid} ({name})" for tid, name in zip(tag_ids, names) if tid not in seen]
    if missing:
        raise CalibrationFailed(
            f"corner tag{'s' if len(missing) > 1 else ''} {', '.join(missing)} not seen "
            f"({dictionary}; give the arena's corners with --corners instead)"
        )
    twice = [str(tid) for tid in tag_ids if len(seen[tid]) > 1]
    if twice:
        raise CalibrationFailed(f"corner tag {', '.join(twice)} seen more than once: which is the corner?")
    centres_px = np.array([seen[tid][0] for tid in tag_ids], dtype=np.float64)
    w, h, d = arena_w_m, arena_h_m, inset_m
    centres_m = np.array([[d, d], [w - d, d], [w - d, h - d], [d, h - d]], dtype=np.float64)
    m = cv2.getPerspectiveTransform(centres_m.astype(np.float32), centres_px.astype(np.float32)).astype(np.float64)
    corners_m = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    return tuple((float(u), float(v)) for u, v in Calibration(m, w, h).to_pixels(corners_m))


def check_corners(corners_px, frame_shape: tuple[int, ...]) -> tuple[tuple[float, float], ...]:
    """The four corners as floats, refused (CalibrationFailed) when they do not make an arena."""
    pts = tuple((float(u), float(v)) for u, v in corners_px)
    try:
        VisionConfig.from_dict({"calibration": {"corners_px": [list(p) for p in pts], "width_m": 1.0, "height_m": 1.0}})
    except ValueError as exc:
        raise CalibrationFailed(str(exc).replace("vision.calibration.corners_px", "the corners")) from None
    h, w = frame_shape[:2]
    inside = sum(-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5 for u, v in pts)
    if inside < 3:
        raise CalibrationFailed(
            f"only {inside} of the four corners lie in the {w} x {h} frame: the camera does not see the arena"
        )
    return pts


# ---------------------------------------------------------------- the markers


def _circular_median_hue(h: np.ndarray) -> float:
    """A robust centre of OpenCV hues (0-179, circular): the median of the hues turned so that
    their circular mean sits in the middle of the range."""
    ang = h.astype(np.float64) * (2 * math.pi / 180.0)
    mean = math.atan2(float(np.sin(ang).mean()), float(np.cos(ang).mean())) * 180.0 / (2 * math.pi)
    shifted = (h.astype(np.float64) - mean + 90.0) % 180.0
    return float((np.median(shifted) + mean - 90.0) % 180.0)


def hue_distance(a: float, b: float) -> float:
    d = abs(a - b) % 180.0
    return min(d, 180.0 - d)


def frame_problem(frame_bgr: np.ndarray) -> str | None:
    """Why a frame cannot be calibrated from, judged on the frame alone (None: it can)."""
    v = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2HSV)[:, :, 2]
    mean_v = float(v.mean())
    if mean_v < MIN_MEAN_VALUE:
        return f"too dark (mean brightness {mean_v:.0f} of 255, at least {MIN_MEAN_VALUE} needed): more light"
    if float((v >= 250).mean()) > 0.25:
        return f"{100 * float((v >= 250).mean()):.0f} % of the frame is saturated white: less light or exposure"
    return None


def find_candidates(frame_bgr: np.ndarray, cal: Calibration, index: int = 0) -> tuple[list[Candidate], list[str]]:
    """The clearly coloured blobs of a marker's size in one frame, and a note for each coloured
    blob of that size cut by the frame's edge."""
    hsv = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2HSV)
    mask = cv2.inRange(hsv, np.array([0, MIN_SATURATION, MIN_VALUE], np.uint8), np.array([179, 255, 255], np.uint8))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # odd: a subset of the mask
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    fh, fw = mask.shape
    out: list[Candidate] = []
    cut: list[str] = []
    for k in range(1, n):
        x, y, w, h, area = (int(v) for v in stats[k])
        u, v = (float(c) for c in centroids[k])
        xm, ym = (float(c) for c in cal.to_arena((u, v)))
        ppm = cal.pixels_per_metre(min(max(xm, 0.0), cal.arena_w_m), min(max(ym, 0.0), cal.arena_h_m))
        lo = AREA_RANGE[0] * (MARKER_SIZE_M * ppm) ** 2
        hi = AREA_RANGE[1] * (TARGET_SIZE_M * ppm) ** 2
        if area > hi:
            continue
        if x == 0 or y == 0 or x + w >= fw or y + h >= fh:
            if area < 0.1 * lo:
                continue
            hue = int(_circular_median_hue(hsv[labels == k][:, 0]))
            cut.append(f"a {hue_name(hue, hue)} blob at pixel ({u:.0f}, {v:.0f}) touches the frame's edge")
            continue
        if area < lo:
            continue
        pix = hsv[labels == k]  # the whole blob: its edge pixels are less saturated, still above the floor's
        out.append(Candidate(index, u, v, xm, ym, float(area), _circular_median_hue(pix[:, 0]), pix))
    return out, cut


def _band_cost(hue: float, word: str) -> float:
    lo, hi = COLOUR_BANDS[word]
    if lo <= hue <= hi:
        return hue_distance(hue, (lo + hi) / 2) / 100.0
    return min(hue_distance(hue, lo), hue_distance(hue, hi)) + 1.0


def _range_gap(hue: float, rng) -> float:
    """How far a hue lies outside an HSV range's hues (0 inside)."""
    (lo, _, _), (hi, _, _) = rng
    return 0.0 if lo <= hue <= hi else min(hue_distance(hue, lo), hue_distance(hue, hi))


def _range_centre(rng) -> float:
    (lo, _, _), (hi, _, _) = rng
    return (lo + hi) / 2.0


def assign_roles(
    cands: list[Candidate],
    cal: Calibration,
    marker_distance_m: float,
    tolerance_m: float,
    words: dict[str, str] | None,
    base: VisionConfig,
) -> dict[str, Candidate]:
    """Which candidate is the rover's front, its back and the target in one frame, or
    CalibrationFailed. The front and back must be marker_distance_m (+- tolerance_m) apart."""
    if len(cands) < 3:
        raise CalibrationFailed(
            f"{len(cands)} coloured marker{'s' if len(cands) != 1 else ''} of a marker's size "
            "in view, 3 needed (the rover's front and back, the target)"
        )

    def cost(role: str, c: Candidate) -> float:
        if words and role in words:
            return _band_cost(c.hue, words[role])
        return hue_distance(c.hue, _range_centre(getattr(base.hsv, role))) / 10.0

    best, best_cost = None, math.inf
    pairs = [
        (f, b)
        for f, b in itertools.permutations(range(len(cands)), 2)
        if abs(math.hypot(cands[f].x_m - cands[b].x_m, cands[f].y_m - cands[b].y_m) - marker_distance_m) <= tolerance_m
    ]
    for f, b in pairs:
        for t in range(len(cands)):
            if t in (f, b):
                continue
            cf, cb, ct = cands[f], cands[b], cands[t]
            total = cost("rover_front", cf) + cost("rover_back", cb) + cost("target", ct)
            if total < best_cost:
                best, best_cost = (cf, cb, ct), total
    if best is None:
        raise CalibrationFailed(
            f"no two coloured markers {marker_distance_m * 100:.0f} cm apart (+-"
            f"{tolerance_m * 100:.0f}): is the rover in view, its markers uncovered?"
        )
    chosen = dict(zip(ROLES, best))
    # A role without the user's word for its colour is taken only near the configured range: a
    # guess between, say, a blue and a magenta square could turn the rover round.
    far = [
        role
        for role, c in chosen.items()
        if not (words and role in words) and _range_gap(c.hue, getattr(base.hsv, role)) > 10
    ]
    if far:
        seen = ", ".join(f"{hue_name(int(c.hue), int(c.hue))}" for c in best)
        raise CalibrationFailed(
            f"the markers seen ({seen}) are not the configuration's colours: say which is "
            "which with --front COLOUR --back COLOUR --target COLOUR"
        )
    if words:
        for role, word in words.items():
            c = chosen[role]
            if _band_cost(c.hue, word) >= 1.0:
                seen = ", ".join(sorted({hue_name(int(x.hue), int(x.hue)) for x in cands}))
                raise CalibrationFailed(f"no {word} marker for the {role.replace('_', ' ')} (colours seen: {seen})")
    return chosen


def propose_ranges(markers: dict[str, list[Candidate]]) -> dict[str, tuple[tuple[int, int, int], tuple[int, int, int]]]:
    """Each role's HSV range from its pixels in every frame (see the module's note), or
    CalibrationFailed: a red marker (its own hues run across 0 and 179), two markers of one
    colour, or ranges that cannot be kept apart."""
    spans: dict[str, list[float]] = {}
    out: dict[str, list[list[int]]] = {}
    for role, cands in markers.items():
        pix = np.concatenate([c.pixels_hsv for c in cands])
        centre = _circular_median_hue(pix[:, 0])
        rel = ((pix[:, 0].astype(np.float64) - centre + 90.0) % 180.0) - 90.0
        lo_h, hi_h = centre + float(np.percentile(rel, 1)), centre + float(np.percentile(rel, 99))
        if lo_h < 0 or hi_h > 179:
            raise CalibrationFailed(
                f"the {role.replace('_', ' ')} marker is red (its hues run across 0 and 179, "
                "which one HSV range cannot hold): use another colour, or ArUco tags"
            )
        # The margin stops at the ends of the hue scale (an orange at H 10 keeps its range).
        spans[role] = [max(0.0, lo_h - HUE_MARGIN), min(179.0, hi_h + HUE_MARGIN), centre]
        s_lo = max(SV_FLOOR, int(SV_FRACTION * float(np.percentile(pix[:, 1], 1))))
        v_lo = max(SV_FLOOR, int(SV_FRACTION * float(np.percentile(pix[:, 2], 1))))
        out[role] = [[0, s_lo, v_lo], [179, 255, 255]]
    # Ranges that meet are cut apart at a hue strictly between the two markers' own, every pair.
    roles = sorted(spans, key=lambda r: spans[r][2])
    for i, a in enumerate(roles):
        for b in roles[i + 1 :]:
            ca, cb = spans[a][2], spans[b][2]
            if cb - ca < 2 * HUE_MARGIN:
                raise CalibrationFailed(
                    f"the {a.replace('_', ' ')} and {b.replace('_', ' ')} markers are the same "
                    f"colour (hues {ca:.0f} and {cb:.0f}): use distinct colours"
                )
            if spans[a][1] >= spans[b][0]:
                cut = min(max((spans[a][1] + spans[b][0]) / 2, ca + 1.0), cb - 1.0)
                spans[a][1] = min(spans[a][1], cut - 0.5)
                spans[b][0] = max(spans[b][0], cut + 0.5)
    for role, (lo_h, hi_h, _centre) in spans.items():
        out[role][0][0], out[role][1][0] = int(math.ceil(lo_h)), int(math.floor(hi_h))
        others = [spans[r][2] for r in spans if r != role]
        if out[role][0][0] > out[role][1][0] or any(out[role][0][0] <= c <= out[role][1][0] for c in others):
            raise CalibrationFailed(
                f"the {role.replace('_', ' ')} marker's hues cannot be kept apart from the "
                "others' (a sticker of mixed colour, or light of another colour on it)"
            )
    return {role: (tuple(lo), tuple(hi)) for role, (lo, hi) in out.items()}  # type: ignore[misc]


# ---------------------------------------------------------------- all of it


def calibrate_camera(
    frames: list[np.ndarray],
    arena_w_m: float,
    arena_h_m: float,
    *,
    corners_px=None,
    words: dict[str, str] | None = None,
    base: VisionConfig | None = None,
    tag_ids: tuple[int, int, int, int] = CORNER_TAG_IDS,
    dictionary: str = CORNER_DICTIONARY,
    inset_m: float = CORNER_INSET_M,
) -> CameraCalibration:
    """Calibrate from frames of a still scene (the rover and the target in view), or
    CalibrationFailed with the reason (naming the frame when there are several)."""
    from ..vision.locator import Locator

    base = base or VisionConfig()
    if not frames:
        raise CalibrationFailed("no frames")

    def where(i: int) -> str:
        return f"frame {i + 1}: " if len(frames) > 1 else ""

    for i, f in enumerate(frames):
        problem = frame_problem(f)
        if problem:
            raise CalibrationFailed(where(i) + problem)
    if corners_px is not None:
        corners = check_corners(corners_px, frames[0].shape)
        how = "points given"
    else:
        found, last = None, None
        for f in frames:
            try:
                found = arena_from_tags(
                    f, arena_w_m, arena_h_m, tag_ids=tag_ids, dictionary=dictionary, inset_m=inset_m
                )
                break
            except CalibrationFailed as exc:
                last = exc
        if found is None:
            raise CalibrationFailed(f"{last}")
        corners = check_corners(found, frames[0].shape)
        how = "corner tags"
    cal = Calibration.from_corners(corners, arena_w_m, arena_h_m)
    markers: dict[str, list[Candidate]] = {role: [] for role in ROLES}
    for i, f in enumerate(frames):
        cands, cut = find_candidates(f, cal, i)
        try:
            chosen = assign_roles(cands, cal, base.marker_distance_m, base.marker_distance_tolerance_m, words, base)
        except CalibrationFailed as exc:
            raise CalibrationFailed(where(i) + str(exc) + (f"; {cut[0]}" if cut else "")) from None
        for role, c in chosen.items():
            markers[role].append(c)
    result = CameraCalibration(corners, arena_w_m, arena_h_m, how, propose_ranges(markers), markers)
    # Checked as the mission will use it: the locator with the new ranges, frame by frame.
    locator = Locator(result.vision(base), arena_w_m, arena_h_m)
    result.frames = len(frames)
    for i, f in enumerate(frames):
        locator.reset()
        d = locator.locate(f)
        result.poses.append(d.rover)
        if d.rover is not None and d.target is not None:
            result.found += 1
        else:
            raise CalibrationFailed(
                where(i) + "with the ranges found the locator still sees no "
                f"{'rover' if d.rover is None else 'target'}: "
                f"{d.reason or d.target_reason} (another marker colour close to these?)"
            )
    return result


# ---------------------------------------------------------------- the check picture


def check_picture(frame_bgr: np.ndarray, result: CameraCalibration, grid_m: float = 0.25) -> np.ndarray:
    """The frame with the arena's outline and a grid every grid_m metres drawn through the
    homography, the markers found (ringed, named) and the rover's pose (an arrow): a calibration
    that is right puts the grid square on the floor's edges and the arrow along the rover."""
    img = frame_bgr.copy()
    cal = result.calibration
    w, h = result.arena_w_m, result.arena_h_m

    def line(p, q, colour, thick=1):
        a, b = cal.to_pixels(np.array([p, q], dtype=np.float64))
        cv2.line(
            img, (int(round(a[0])), int(round(a[1]))), (int(round(b[0])), int(round(b[1]))), colour, thick, cv2.LINE_AA
        )

    for x in np.arange(grid_m, w, grid_m):
        line((x, 0.0), (x, h), (200, 200, 60))
    for y in np.arange(grid_m, h, grid_m):
        line((0.0, y), (w, y), (200, 200, 60))
    for p, q in (((0, 0), (w, 0)), ((w, 0), (w, h)), ((w, h), (0, h)), ((0, h), (0, 0))):
        line(p, q, (60, 220, 255), 2)
    labels = {"rover_front": "front", "rover_back": "back", "target": "target"}
    for role, cands in result.markers.items():
        c = cands[0]
        r = max(6, int(math.sqrt(c.area_px)))
        cv2.circle(img, (int(round(c.u_px)), int(round(c.v_px))), r, (255, 255, 255), 1, cv2.LINE_AA)
        cv2.putText(
            img,
            labels[role],
            (int(c.u_px) + r + 2, int(c.v_px) + 4),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.4,
            (255, 255, 255),
            1,
            cv2.LINE_AA,
        )
    pose = result.poses[0] if result.poses else None
    if pose is not None:
        hd = math.radians(pose.heading_deg)
        tip = (pose.x_m + 0.15 * math.sin(hd), pose.y_m + 0.15 * math.cos(hd))
        a, b = cal.to_pixels(np.array([[pose.x_m, pose.y_m], tip]))
        cv2.arrowedLine(
            img,
            (int(round(a[0])), int(round(a[1]))),
            (int(round(b[0])), int(round(b[1]))),
            (0, 0, 255),
            2,
            cv2.LINE_AA,
            tipLength=0.25,
        )
        cv2.putText(
            img,
            f"({pose.x_m:.2f}, {pose.y_m:.2f}) m {pose.heading_deg:.0f} deg",
            (int(a[0]) + 8, int(a[1]) - 8),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            (0, 0, 255),
            1,
            cv2.LINE_AA,
        )
    return img
