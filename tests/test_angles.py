"""rovernav.angles: one convention for the host, the firmware's (angles.h)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from rovernav.angles import compass_deg, heading_cdeg, wrap_deg, wrap_rad

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@given(finite)
def test_each_wrap_lands_in_its_range_and_keeps_the_direction(a):
    r, d, c = wrap_rad(a), wrap_deg(a), compass_deg(a)
    assert -math.pi < r <= math.pi and -180.0 < d <= 180.0 and 0.0 <= c < 360.0
    assert math.isclose(math.cos(r), math.cos(a), abs_tol=1e-6) and math.isclose(math.sin(r), math.sin(a), abs_tol=1e-6)
    assert abs(math.remainder(d - a, 360.0)) < 1e-6 and abs(math.remainder(c - a, 360.0)) < 1e-6
    assert -18000 < heading_cdeg(a) <= 18000


def test_the_ends_are_the_firmwares():
    # angles.h: wrap_rad into (-pi, pi], rad_to_cdeg into (-18000, 18000]
    assert wrap_rad(math.pi) == math.pi and wrap_rad(-math.pi) == math.pi and wrap_rad(3 * math.pi) == math.pi
    assert wrap_deg(-180.0) == 180.0 and wrap_deg(540.0) == 180.0 and wrap_deg(-179.5) == -179.5
    assert heading_cdeg(-180.0) == 18000 and heading_cdeg(-179.996) == 18000 and heading_cdeg(359.0) == -100
    assert compass_deg(-1e-15) == 0.0 and compass_deg(-90.0) == 270.0 and str(compass_deg(-0.0)) == "0.0"


def test_arrays_wrap_as_floats_do():
    a = np.array([-3 * math.pi, -math.pi, -1e-17, 0.0, math.pi, 7.0, -1e6])
    assert list(wrap_rad(a)) == [wrap_rad(float(v)) for v in a]
    d = np.degrees(a)
    assert list(wrap_deg(d)) == [wrap_deg(float(v)) for v in d]
    assert list(compass_deg(d)) == [compass_deg(float(v)) for v in d]
