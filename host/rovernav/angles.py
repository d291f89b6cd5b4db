"""Angles on the host, one convention: the firmware's (firmware/lib/core/angles.h).

    wrap_rad(a)       radians into (-pi, pi]          (angles.h wrap_rad)
    wrap_deg(a)       degrees into (-180, 180]
    heading_cdeg(a)   degrees to whole centidegrees in (-18000, 18000], as on the wire
                      (FIX, STATUS, OBSTACLE; angles.h rad_to_cdeg)
    compass_deg(a)    degrees into [0, 360): a heading as people and scenario files write it

Headings: 0 = +y (up the arena), clockwise positive. Every function takes a float or a NumPy
array; the end of the range is the same either way, also where floating-point rounding would
land a value on the other end (-pi).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_rad(a):
    """`a` [rad] folded into (-pi, pi]."""
    w = math.pi - (math.pi - a) % TWO_PI
    if isinstance(w, np.ndarray):
        return np.where(w <= -math.pi, w + TWO_PI, w)
    return w + TWO_PI if w <= -math.pi else w


def wrap_deg(a):
    """`a` [deg] folded into (-180, 180]."""
    w = 180.0 - (180.0 - a) % 360.0
    if isinstance(w, np.ndarray):
        return np.where(w <= -180.0, w + 360.0, w)
    return w + 360.0 if w <= -180.0 else w


def heading_cdeg(a_deg: float) -> int:
    """A heading [deg] as the wire's whole centidegrees in (-18000, 18000]."""
    c = round(wrap_deg(a_deg) * 100)
    return 18000 if c <= -18000 else c


def compass_deg(a):
    """`a` [deg] folded into [0, 360)."""
    w = a % 360.0
    if isinstance(w, np.ndarray):
        return np.where(w >= 360.0, 0.0, w)
    return 0.0 if w >= 360.0 else w + 0.0  # -1e-15 % 360 is 360.0; + 0.0 turns -0.0 into 0.0
