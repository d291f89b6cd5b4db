"""The simulator's world geometry: the rover's footprint against boxes, walls and posts
(contact, clearance, what it touches), rays, echoes and the sonar's cone.
(Split from test_sim.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rovernav.sim.world import Box, Post, Wall, World, footprint

# ---------------------------------------------------------------- footprint, clearance and contact


def test_footprint_contact_and_clearance():
    world = World(2.0, 2.0, [Box(1.0, 1.0, 0.2, 0.2)])
    assert world.clearance_m(1.0, 1.3, 0.0) == pytest.approx(0.095, abs=1e-6)  # nose 0.105 ahead
    assert world.collides(1.0, 1.2, 0.0)
    assert world.collides(0.05, 1.5, 0.0)  # through the wall
    assert world.clearance_bound_m(1.0, 1.5) <= world.clearance_m(1.0, 1.5, 37.0)


def test_the_world_names_what_the_rover_touches():
    w = World(2.0, 2.0, [Box(1.0, 1.0, 0.2, 0.2, known=False)])
    assert w.touching(1.0, 0.8, 0.0).startswith("obstacle 1 (unknown box at (1.00, 1.00) m")
    assert w.touching(0.05, 1.5, 0.0) == "the left wall"


# ---------------------------------------------------------------- walls and posts


def _outline(points, step_m=0.0005):
    pts = []
    for a, b in zip(points, points[1:] + points[:1]):
        n = max(2, int(math.dist(a, b) / step_m) + 1)
        pts.append(np.asarray(a) + (np.asarray(b) - np.asarray(a)) * np.linspace(0, 1, n)[:, None])
    return np.concatenate(pts)


def _inside(p, poly):
    """Whether point p lies inside a convex polygon (either winding)."""
    s = [(b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) for a, b in zip(poly, poly[1:] + poly[:1])]
    return all(v >= 0 for v in s) or all(v <= 0 for v in s)


def _brute_clearance(fp, shape_outline, shape_poly_or_post):
    """Distance between the footprint and a shape from their sampled outlines (0 if they overlap)."""
    fp = [tuple(p) for p in fp]
    a = _outline(fp)
    d = np.hypot(a[:, None, 0] - shape_outline[None, :, 0], a[:, None, 1] - shape_outline[None, :, 1]).min()
    if isinstance(shape_poly_or_post, Post):
        p = shape_poly_or_post
        if _inside((p.x_m, p.y_m), fp) or any(math.dist(q, (p.x_m, p.y_m)) <= p.radius_m for q in fp):
            return 0.0
    elif any(_inside(q, shape_poly_or_post) for q in fp) or any(_inside(q, fp) for q in shape_poly_or_post):
        return 0.0
    return float(d)


@pytest.mark.slow
def test_clearance_to_walls_and_posts_is_exact_at_any_heading():
    wall = Wall(1.6, 1.6, 2.4, 2.4, 0.06, known=False)
    post = Post(2.0, 2.0, 0.07)
    rng = np.random.default_rng(5)
    angles = np.linspace(0, 2 * np.pi, 3000, endpoint=False)
    post_outline = np.stack([post.x_m + post.radius_m * np.cos(angles), post.y_m + post.radius_m * np.sin(angles)], 1)
    for shape, outline, ref in ((wall, _outline(wall.corners()), wall.corners()), (post, post_outline, post)):
        world = World(4.0, 4.0, [], [wall] if shape is wall else [], [post] if shape is post else [])
        contacts = clear = 0
        for _ in range(60):
            cx, cy = 2.0, 2.0
            x, y = cx + rng.uniform(-0.35, 0.35), cy + rng.uniform(-0.35, 0.35)
            h = rng.uniform(-180, 180)
            fp = footprint(x, y, h)
            arena = min(fp[:, 0].min(), fp[:, 1].min(), 4.0 - fp[:, 0].max(), 4.0 - fp[:, 1].max())
            expected = min(_brute_clearance(fp, outline, ref), arena)
            assert arena > 0.5  # the shape, not the arena's wall, is what is measured
            got = world.clearance_m(x, y, h)
            assert got == pytest.approx(expected, abs=1e-3), (shape, x, y, h)
            assert world.clearance_bound_m(x, y) <= got + 1e-12
            assert world.collides(x, y, h) == (got <= 0.0)
            contacts += got == 0.0
            clear += got > 0.01
        assert contacts >= 5 and clear >= 5  # both cases were tried


def test_the_world_names_the_wall_or_post_it_touches():
    w = World(
        2.0,
        2.0,
        [Box(0.3, 1.7, 0.1, 0.1)],
        [Wall(1.0, 0.2, 1.0, 0.9, 0.05), Wall(0.2, 1.2, 0.8, 1.5, 0.04, known=False)],
        [Post(1.6, 1.5, 0.05, known=False)],
    )
    assert w.touching(1.0, 1.0, 0.0) == "wall 1 (known, from (1.00, 0.20) to (1.00, 0.90) m, 0.05 m thick)"
    assert w.touching(0.5, 1.25, 30.0).startswith("wall 2 (unknown, from (0.20, 1.20) to (0.80, 1.50) m")
    assert w.collides(0.5, 1.25, 30.0)
    assert w.touching(1.6, 1.36, 0.0) == "post 1 (unknown, at (1.60, 1.50) m, radius 0.050 m)"
    assert w.collides(1.6, 1.36, 0.0) and not w.collides(1.6, 1.33, 0.0)
    assert w.touching(0.05, 0.5, 0.0) == "the left wall"


def test_rays_stop_at_walls_and_posts():
    wall = Wall(1.0, 0.5, 2.0, 1.5, 0.1)  # at 45°
    w = World(3.0, 3.0, [], [wall], [Post(0.5, 2.0, 0.1)])
    # from (1.0, 1.5) straight to +x (90°): the centre line is x - y = 0.5, the upper-left face
    # half the thickness off it, x - y = 0.5 - 0.05·√2
    face = 0.5 - 0.05 * math.sqrt(2)
    assert w.ray_m(1.0, 1.5, 90.0, 4.0) == pytest.approx((1.5 + face) - 1.0)
    assert w.ray_m(0.5, 1.0, 0.0, 4.0) == pytest.approx(0.9)  # to the post's near side
    assert w.ray_m(0.5 + 0.0999, 1.0, 0.0, 4.0) < 1.0  # grazing its edge
    assert w.ray_m(0.5 + 0.1001, 1.0, 0.0, 4.0) == pytest.approx(2.0)  # past it, to the arena's top
    assert w.ray_m(2.9, 0.1, 135.0, 4.0) == pytest.approx(0.1 * math.sqrt(2))  # the arena's corner
    # beyond the wall's square end: the ray along its centre line meets the end face
    assert w.ray_m(0.5, 0.0, 45.0, 4.0) == pytest.approx(math.hypot(0.5, 0.5))
    assert w.ray_m(1.0, 1.0, 0.0, 0.2) == 0.2  # nothing within max_m: max_m


def test_a_flat_face_echoes_only_near_its_normal_and_a_post_always():
    # A wall along x, its lower face at y = 1.0; the sensor 0.4 m below it.
    w = World(4.0, 4.0, [], [Wall(0.5, 1.025, 3.5, 1.025, 0.05)], [Post(2.0, 2.6, 0.05)])
    for limit in (40.0, 90.0):
        assert w.echo_m(2.0, 0.6, 20.0, 4.0, limit) == pytest.approx(0.4 / math.cos(math.radians(20)))
    assert w.echo_m(2.0, 0.6, 60.0, 4.0, 40.0) == 4.0  # sent away: nothing heard
    assert w.echo_m(2.0, 0.6, 60.0, 4.0, 90.0) == pytest.approx(0.8)
    assert w.ray_m(2.0, 0.6, 60.0, 4.0) == pytest.approx(0.8)  # the ray still stops there
    # the same for an oblique wall (normal at 30° from +y, i.e. the wall runs at 120°)
    ox, oy = 2.0, 2.0
    u = (math.sin(math.radians(120)), math.cos(math.radians(120)))
    slanted = World(4.0, 4.0, [], [Wall(ox - u[0], oy - u[1], ox + u[0], oy + u[1], 0.04)])
    sx, sy = ox - 0.5 * math.sin(math.radians(30)), oy - 0.5 * math.cos(math.radians(30))  # 0.5 m off, on the normal
    assert slanted.echo_m(sx, sy, 30.0 + 20.0, 4.0, 40.0) == pytest.approx(0.48 / math.cos(math.radians(20)))
    assert slanted.echo_m(sx, sy, 30.0 - 20.0, 4.0, 40.0) == pytest.approx(0.48 / math.cos(math.radians(20)))
    assert slanted.echo_m(sx, sy, 30.0 + 60.0, 4.0, 40.0) == 4.0
    # a post echoes whatever the angle its surface is met at
    for dx in (0.0, 0.03, 0.049):
        assert w.echo_m(2.0 + dx, 2.0, 0.0, 4.0, 40.0) == pytest.approx(0.6 - math.sqrt(0.05**2 - dx**2))


def test_the_sonar_cone_hears_a_corner_but_not_a_face_met_obliquely():
    # A long wall met 60° off its normal: no echo from its face, whether the beam's cone is narrow or not.
    w = World(4.0, 4.0, [], [Wall(0.2, 2.0, 3.8, 2.0, 0.05)])
    assert w.sonar_m(1.0, 1.5, 60.0, 15.0, 4.0, 40.0) == 4.0
    assert w.sonar_m(1.0, 1.5, 60.0, 15.0, 4.0, 90.0) == pytest.approx(0.475 / math.cos(math.radians(52.5)))
    assert w.sonar_m(1.0, 1.5, 20.0, 15.0, 4.0, 40.0) == pytest.approx(0.475 / math.cos(math.radians(12.5)))
    # the wall's end corner inside the cone echoes, though its faces are met beyond 40°
    end = World(4.0, 4.0, [], [Wall(0.2, 2.0, 1.6, 2.0, 0.05)])
    corner = (1.6, 1.975)
    bearing = math.degrees(math.atan2(corner[0] - 1.0, corner[1] - 1.5))
    assert bearing > 47.5  # every ray of the cone meets the lower face more than 40° off its normal
    assert end.sonar_m(1.0, 1.5, bearing + 3.0, 15.0, 4.0, 40.0) == pytest.approx(math.dist((1.0, 1.5), corner))
    assert end.sonar_m(1.0, 1.5, bearing + 10.0, 15.0, 2.0, 40.0) == 2.0  # the corner outside the cone
    # a corner hidden behind the obstacle itself does not echo
    assert end.corner_echo_m(1.0, 1.5, math.degrees(math.atan2(0.6, 0.525)), 2.0, 4.0) == 4.0


def test_the_footprint_in_plain_floats_is_the_vector_formula_bit_for_bit():
    # The clearance test uses the corners as plain floats; the reference is the vector formula.
    import math
    import random

    import numpy as np

    from rovernav.sim.world import ROVER_LENGTH_M, ROVER_WIDTH_M, footprint

    rnd = random.Random(11)
    for _ in range(20000):
        x, y, heading = rnd.uniform(-1, 3), rnd.uniform(-1, 3), rnd.uniform(-720, 720)
        h = math.radians(heading)
        f, r, c = np.array([math.sin(h), math.cos(h)]), np.array([math.cos(h), -math.sin(h)]), np.array([x, y])
        hl, hw = ROVER_LENGTH_M / 2, ROVER_WIDTH_M / 2
        want = np.array([c + hl * f - hw * r, c + hl * f + hw * r, c - hl * f + hw * r, c - hl * f - hw * r])
        assert np.array_equal(footprint(x, y, heading), want)
