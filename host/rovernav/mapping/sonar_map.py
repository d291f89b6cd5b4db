"""A log-odds occupancy grid built from every sonar reading (Moravec and Elfes, 1985).

Each cell holds L = log(p / (1 - p)) of being occupied, 0 (p = 0.5) while nothing is known.
A reading is the rover's pose when it pinged, the servo's bearing, and a range (or none: no
echo within `max_range_m`). The HC-SR04 answers with the NEAREST surface anywhere in its cone,
which makes the inverse sensor model:

    cells in the cone nearer than the range (less `band_m`)   L += free_logodds  (nothing there)
    cells in the cone within `band_m` of the range (the arc)   L += occupied_logodds
    cells in the cone out to max_range_m, when no echo came    L += free_logodds
    cells behind the arc                                      unchanged (unknown)
    cells under the rover's own body                          free (it stands there)

The arc takes every cell any part of which lies in the cone; the free marks only the cells whose
centre does (a cell the cone's edge cuts may hold a corner in the part the sound missed), unless
the model's `clear_cut_cells` is set: the host keeps a second map so (rovernav.mapping.learned_map).

An echo already explained, because its arc meets the arena's wall, a known obstacle or cells
already believed occupied, raises only those cells, not the rest of its arc: a second look
at a known face sharpens it where a fresh arc would smear it wider each time it is seen from
a new place (and close corridors the last trip drove through). Its free interior is folded
in all the same.

A cell is believed occupied when L >= occupied_threshold. One echo marks its whole arc (the
obstacle may stand anywhere across the 15-degree cone); another reading whose cone passes
through part of that arc without an echo there carves it away, so repeated readings sharpen
the map instead of smearing it. Nothing is dropped, and nothing is assumed behind a face.

Unknown space (|L| small) is planned through optimistically: the rover's sweeps every 0.3 m
and its forward reflex look again before it gets there. The planner's layer is the known
obstacles' inflation OR the believed-occupied cells inflated by the same radius (robot radius +
sonar margin): `apply(grid)` writes it into an OccupancyGrid.

The cell layout is the planner's (rovernav.planning.grid): arrays [iy, ix], cell centres at
((ix + 0.5)·res, (iy + 0.5)·res) metres.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from ..angles import wrap_rad
from ..link.messages_gen import PARAMS, Param
from ..validate import check_grid
from ..vehicle_gen import BODY_WIDTH_MM, SONAR_MAX_RANGE_MM

#: The sensor's range [m] (protocol/vehicle.toml): silence says nothing of what lies past it,
#: whatever range a reading (or an old map file) claims.
SENSOR_MAX_RANGE_M = SONAR_MAX_RANGE_MM / 1000.0


def sonar_origin(x_m: float, y_m: float, heading_deg: float, offset_m: float) -> tuple[float, float]:
    """Where the ranger sits [m]: `offset_m` ahead of the rover's centre (x_m, y_m) along its
    heading (0 = +y, clockwise). The one definition on the host (the firmware's is
    core::sonar_origin, firmware/lib/core/sonar_geometry.h)."""
    h = math.radians(heading_deg)
    return x_m + offset_m * math.sin(h), y_m + offset_m * math.cos(h)


def echo_point(
    x_m: float, y_m: float, heading_deg: float, bearing_deg: float, range_m: float, offset_m: float
) -> tuple[float, float]:
    """Where an echo lies [m]: on the beam's axis (heading + the servo's bearing, clockwise), at
    `range_m` from the ranger. The obstacle may stand anywhere across the cone at that range:
    the map marks the whole arc; pictures and logs show this point."""
    sx, sy = sonar_origin(x_m, y_m, heading_deg, offset_m)
    b = math.radians(heading_deg + bearing_deg)
    return sx + range_m * math.sin(b), sy + range_m * math.cos(b)


@dataclasses.dataclass(frozen=True)
class SensorModel:
    """The inverse sensor model's numbers (log-odds are dimensionless, lengths in metres)."""

    cone_deg: float = PARAMS[Param.SONAR_CONE_CDEG].default / 100.0  # the beam's width (HC-SR04: 15)
    occupied_logodds: float = 1.0  # added on the arc of an echo (p 0.5 -> 0.73)
    free_logodds: float = -0.5  # added inside the cone before the arc (p 0.5 -> 0.38)
    occupied_threshold: float = 0.6  # believed occupied at or above this (p >= 0.65)
    clamp_logodds: float = 4.0  # |L| never exceeds this, so a change of world can be learned
    band_m: float = 0.03  # half-thickness of the arc, plus the reading's position sd
    body_radius_m: float = BODY_WIDTH_MM / 2000.0  # cells within this of the rover's centre are free (half its width)
    clear_cut_cells: bool = False  # silence clears cells the cone's edge only cuts too (the open map)


@dataclasses.dataclass(frozen=True)
class SonarReading:
    """One ping as the rover reported it: its estimated pose, the servo's bearing off the heading
    (clockwise positive), the range from the sensor, or None for no echo within max_range_m."""

    x_m: float
    y_m: float
    heading_deg: float
    bearing_deg: float
    range_m: float | None
    max_range_m: float
    sd_m: float = 0.0


class SonarMap:
    """Log-odds occupancy over a `width_m` x `height_m` arena in cells of `resolution_m`.

    `sonar_offset_m`: the sensor sits this far ahead of the rover's centre.
    """

    def __init__(
        self,
        width_m: float,
        height_m: float,
        resolution_m: float,
        sonar_offset_m: float,
        model: SensorModel = SensorModel(),
        known: np.ndarray | None = None,
    ):
        self.width_m, self.height_m, self.resolution_m = float(width_m), float(height_m), float(resolution_m)
        check_grid(self.width_m, self.height_m, self.resolution_m, "the sonar map's arena")
        self.nx = max(1, int(math.ceil(self.width_m / resolution_m - 1e-9)))
        self.ny = max(1, int(math.ceil(self.height_m / resolution_m - 1e-9)))
        self.xs = (np.arange(self.nx) + 0.5) * resolution_m
        self.ys = (np.arange(self.ny) + 0.5) * resolution_m
        self.sonar_offset_m = float(sonar_offset_m)
        self.model = model
        self.logodds = np.zeros((self.ny, self.nx), dtype=np.float32)
        self.known = np.zeros((self.ny, self.nx), dtype=bool) if known is None else np.asarray(known, dtype=bool)
        self.readings: list[SonarReading] = []
        self.closed_cells = 0  # how many cells the last update newly holds occupied

    @property
    def occupied(self) -> np.ndarray:
        """Cells the sonar found occupied that the known obstacles do not already hold (bool [iy, ix])."""
        return (self.logodds >= self.model.occupied_threshold) & ~self.known

    def probability(self) -> np.ndarray:
        """p(occupied) of every cell."""
        return 1.0 / (1.0 + np.exp(-self.logodds.astype(np.float64)))

    def sensor_xy(self, r: SonarReading) -> tuple[float, float]:
        return sonar_origin(r.x_m, r.y_m, r.heading_deg, self.sonar_offset_m)

    def update(self, r: SonarReading) -> int:
        """Fold one reading in; returns how many cells crossed the occupied threshold (either way).
        `closed_cells` then says how many of them it newly holds occupied."""
        m = self.model
        before = self.occupied
        self.readings.append(r)
        sx, sy = self.sensor_xy(r)
        band = m.band_m + max(0.0, r.sd_m)
        silent_m = min(r.max_range_m, SENSOR_MAX_RANGE_M)
        reach = (r.range_m + band) if r.range_m is not None else silent_m
        res = self.resolution_m
        c0, c1 = max(int((sx - reach) / res) - 1, 0), min(int((sx + reach) / res) + 2, self.nx)
        r0, r1 = max(int((sy - reach) / res) - 1, 0), min(int((sy + reach) / res) + 2, self.ny)
        if c0 < c1 and r0 < r1:
            dx = self.xs[c0:c1][None, :] - sx
            dy = self.ys[r0:r1][:, None] - sy
            d = np.hypot(dx, dy)
            axis = math.radians(r.heading_deg + r.bearing_deg)
            off = np.abs(wrap_rad(np.arctan2(dx, dy) - axis))
            # An echo may come from any cell part of which is in the cone: half a cell's angular size
            # more than the half-cone. Silence clears only the cells whose centre is in it: a cell the
            # cone's edge cuts may hold a surface (a box's corner) in its part the sound missed.
            nominal = math.radians(m.cone_deg) / 2
            cone = off <= nominal + np.arctan2(0.5 * res, np.maximum(d, 1e-6))
            clear = cone if m.clear_cut_cells else off <= nominal
            window = self.logodds[r0:r1, c0:c1]
            if r.range_m is None:
                window[clear & (d <= silent_m)] += m.free_logodds
            else:
                window[clear & (d < r.range_m - band)] += m.free_logodds
                arc = cone & (np.abs(d - r.range_m) <= band)
                explains = arc & ((window >= m.occupied_threshold) | self.known[r0:r1, c0:c1])
                if explains.any():
                    window[explains] += m.occupied_logodds
                elif not self._arc_meets_wall(sx, sy, axis, r.range_m + band):
                    window[arc] += m.occupied_logodds
        self._free_body(r.x_m, r.y_m)
        np.clip(self.logodds, -m.clamp_logodds, m.clamp_logodds, out=self.logodds)
        after = self.occupied
        self.closed_cells = int(np.count_nonzero(after & ~before))
        return int(np.count_nonzero(before != after))

    def _arc_meets_wall(self, sx: float, sy: float, axis_rad: float, range_m: float) -> bool:
        """Whether some of the cone at `range_m` lies on or beyond the arena's border (the wall)."""
        half = math.radians(self.model.cone_deg) / 2
        a = axis_rad + np.linspace(-half, half, 9)
        px, py = sx + range_m * np.sin(a), sy + range_m * np.cos(a)
        return bool(np.any((px <= 0) | (py <= 0) | (px >= self.width_m) | (py >= self.height_m)))

    def _free_body(self, x_m: float, y_m: float) -> None:
        """The rover stands here: the cells under its body are not obstacles."""
        res, rad = self.resolution_m, self.model.body_radius_m
        c0, c1 = max(int((x_m - rad) / res), 0), min(int((x_m + rad) / res) + 1, self.nx)
        r0, r1 = max(int((y_m - rad) / res), 0), min(int((y_m + rad) / res) + 1, self.ny)
        if c0 < c1 and r0 < r1:
            d = np.hypot(self.xs[c0:c1][None, :] - x_m, self.ys[r0:r1][:, None] - y_m)
            window = self.logodds[r0:r1, c0:c1]
            np.minimum(window, np.where(d <= rad, self.model.free_logodds, np.inf), out=window)

    def inflated(self, radius_m: float) -> np.ndarray:
        """Cells whose centre lies within radius_m of a believed-occupied cell's centre."""
        occ = self.occupied.astype(np.uint8)
        if not occ.any():
            return np.zeros_like(occ, dtype=bool)
        k = int(math.floor(radius_m / self.resolution_m + 1e-9))
        yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
        kernel = ((xx * xx + yy * yy) * self.resolution_m**2 <= radius_m**2 + 1e-12).astype(np.uint8)
        return cv2.dilate(occ, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
