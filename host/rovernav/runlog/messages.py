"""What the run log's channels carry, made from the run's values: JSON records, link frames as the
log keeps them, Foxglove poses, and the scenes and grid drawn for the arena, the sonar's echoes
and the learned map. No state: the RunLog (writer.py) decides what is logged when.

The foxglove-sdk's messages are imported where they are built, as writer.py does: this module is
loaded with the writer, when a run logs.
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..link import messages_gen as mg
from ..link.framing import CRC_BYTES, HEADER_BYTES, cobs_decode
from .channels import ARENA_FRAME


def to_json(data: dict) -> bytes:
    # Python's JSON writes every float exactly (repr): what replay reads back is what was logged.
    return json.dumps(data, allow_nan=False, separators=(",", ":")).encode()


def _quat(heading_deg: float):
    from foxglove.messages import Quaternion

    yaw = math.pi / 2 - math.radians(heading_deg)  # heading: 0 = +y, clockwise; yaw: from +x, anticlockwise
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def pose(x_m: float, y_m: float, heading_deg: float = 90.0, z_m: float = 0.0):
    from foxglove.messages import Pose, Vector3

    return Pose(position=Vector3(x=float(x_m), y=float(y_m), z=float(z_m)), orientation=_quat(heading_deg))


def color(r: float, g: float, b: float, a: float = 1.0):
    from foxglove.messages import Color

    return Color(r=r, g=g, b=b, a=a)


def poses_along(points) -> list:
    """Poses at `points` [(x, y, ...)], each facing the next point (the last as the one before it)."""
    headings = [math.degrees(math.atan2(b[0] - a[0], b[1] - a[1])) for a, b in zip(points, points[1:])]
    headings.append(headings[-1] if headings else 0.0)
    return [pose(p[0], p[1], h) for p, h in zip(points, headings)]


class GrowingPoses:
    """`poses_along` of a list of points that only grows (the driven path), made as it grows: a
    point's pose is made once its next point is known, and only the last one each time (the whole
    path again each time made a run's log cost grow with the square of its length; each publish
    still hands the log the whole path)."""

    def __init__(self) -> None:
        self._done: list = []

    def poses(self, points) -> list:
        done = self._done
        for i in range(len(done), len(points) - 1):
            a, b = points[i], points[i + 1]
            done.append(pose(a[0], a[1], math.degrees(math.atan2(b[0] - a[0], b[1] - a[1]))))
        if not points:
            return []
        last, n = points[-1], len(points)
        heading = math.degrees(math.atan2(last[0] - points[n - 2][0], last[1] - points[n - 2][1])) if n > 1 else 0.0
        return [*done, pose(last[0], last[1], heading)]


def message_record(message, seq: int, n: int, t_s: float, counter: int | None = None) -> dict:
    """A link frame as the log keeps it: its payload (what replay decodes) and its fields (to read)."""
    return {
        "n": n,
        "t_s": t_s,
        "type": message.NAME,
        "id": message.ID,
        "seq": seq,
        "payload_hex": message.pack().hex(),
        "fields": message.to_dict(),
        "counter": counter,
    }


def sent_frame(data: bytes) -> tuple[int, int, int | None] | None:
    """(message id, sequence number, counter) of the one frame `data` holds as the link writes it
    (COBS, delimiter last); the counter None for an unsigned frame. None if `data` is not exactly
    one well-formed frame (the CRC is not checked: these are the host's own bytes)."""
    if len(data) < 2 or data[-1] != 0 or 0 in data[:-1]:
        return None
    raw = cobs_decode(data[:-1])
    if raw is None or len(raw) < HEADER_BYTES + CRC_BYTES:
        return None
    version, msg_id, seq = raw[0] & ~mg.ADDRESS_MASK, raw[1], raw[2]  # at any rover's address ([fleet])
    if version == mg.PROTOCOL_VERSION:
        return msg_id, seq, None
    end = len(raw) - CRC_BYTES - mg.SIGN_TAG_BYTES  # the counter ends where the tag begins
    if version != mg.PROTOCOL_VERSION | mg.SIGN_FLAG or end - mg.SIGN_COUNTER_BYTES < HEADER_BYTES:
        return None
    return msg_id, seq, int.from_bytes(raw[end - mg.SIGN_COUNTER_BYTES : end], "little")


def echo_scene(reading, sonar_offset_m: float, n: int, stamp):
    """The `n`th echo heard, as a scene: the beam from the sonar to it, and the point it marks."""
    from foxglove.messages import LinePrimitive, Point3, SceneEntity, SceneUpdate, SpherePrimitive, Vector3

    from ..mapping import echo_point, sonar_origin

    r, off = reading, sonar_offset_m
    sx, sy = sonar_origin(r.x_m, r.y_m, r.heading_deg, off)
    ex, ey = echo_point(r.x_m, r.y_m, r.heading_deg, r.bearing_deg, r.range_m, off)
    entity = SceneEntity(
        timestamp=stamp,
        frame_id=ARENA_FRAME,
        id=f"echo-{n}",
        lines=[
            LinePrimitive(
                thickness=0.004,
                points=[Point3(x=sx, y=sy, z=0.05), Point3(x=ex, y=ey, z=0.05)],
                color=color(1.0, 0.6, 0.0, 0.5),
            )
        ],
        spheres=[
            SpherePrimitive(
                pose=pose(ex, ey, z_m=0.05), size=Vector3(x=0.02, y=0.02, z=0.02), color=color(1.0, 0.0, 0.0)
            )
        ],
    )
    return SceneUpdate(entities=[entity])


def occupancy_grid(learned_map, stamp):
    """The learned map as a Grid: the sonar's occupancy [%] and the planner's inflated cells."""
    from foxglove.messages import Grid, PackedElementField, PackedElementFieldNumericType, Vector2

    g = learned_map.grid
    sonar = learned_map.sonar
    pct = np.clip(np.rint(sonar.probability() * 100), 0, 100).astype(np.uint8)
    pct[sonar.known] = 100
    inflated = g.inflated[: pct.shape[0], : pct.shape[1]].astype(np.uint8) * 100
    cells = np.stack([pct, inflated], axis=-1)  # rows from y = 0 up, as Grid wants
    ny, nx = pct.shape
    return Grid(
        timestamp=stamp,
        frame_id=ARENA_FRAME,
        pose=pose(0.0, 0.0),
        column_count=nx,
        cell_size=Vector2(x=sonar.resolution_m, y=sonar.resolution_m),
        row_stride=nx * 2,
        cell_stride=2,
        fields=[
            PackedElementField(name="occupied_pct", offset=0, type=PackedElementFieldNumericType.Uint8),
            PackedElementField(name="inflated", offset=1, type=PackedElementFieldNumericType.Uint8),
        ],
        data=cells.tobytes(),
    )


def arena_scene(sc, truth: bool, stamp):
    """The arena of scenario `sc` as a scene: floor, obstacles, walls, posts (the unknown ones only
    with `truth`), the start and the target."""
    from foxglove.messages import (
        CubePrimitive,
        CylinderPrimitive,
        SceneEntity,
        SceneUpdate,
        SpherePrimitive,
        Vector3,
    )

    known, unknown = color(0.6, 0.6, 0.6, 0.9), color(0.9, 0.15, 0.15, 0.6)
    height = 0.10
    cubes, cylinders = [], []
    for o in sc.obstacles:
        if o.known or truth:
            cubes.append(
                CubePrimitive(
                    pose=pose(o.x_m, o.y_m, z_m=height / 2),
                    size=Vector3(x=o.w_m, y=o.h_m, z=height),
                    color=known if o.known else unknown,
                )
            )
    for w in sc.walls:
        if w.known or truth:
            heading = math.degrees(math.atan2(w.x1_m - w.x0_m, w.y1_m - w.y0_m))
            cubes.append(
                CubePrimitive(
                    pose=pose((w.x0_m + w.x1_m) / 2, (w.y0_m + w.y1_m) / 2, heading + 90.0, z_m=height / 2),
                    size=Vector3(x=w.thickness_m, y=w.length_m, z=height),
                    color=known if w.known else unknown,
                )
            )
    for p in sc.posts:
        if p.known or truth:
            cylinders.append(
                CylinderPrimitive(
                    pose=pose(p.x_m, p.y_m, z_m=height / 2),
                    size=Vector3(x=2 * p.radius_m, y=2 * p.radius_m, z=height),
                    bottom_scale=1.0,
                    top_scale=1.0,
                    color=known if p.known else unknown,
                )
            )
    floor = CubePrimitive(
        pose=pose(sc.arena.width_m / 2, sc.arena.height_m / 2, z_m=-0.005),
        size=Vector3(x=sc.arena.width_m, y=sc.arena.height_m, z=0.01),
        color=color(0.15, 0.15, 0.15, 1.0),
    )
    marks = [
        SpherePrimitive(
            pose=pose(sc.start.x_m, sc.start.y_m, z_m=0.02),
            size=Vector3(x=0.06, y=0.06, z=0.02),
            color=color(0.1, 0.8, 0.1),
        ),
        SpherePrimitive(
            pose=pose(sc.target.x_m, sc.target.y_m, z_m=0.02),
            size=Vector3(x=0.08, y=0.08, z=0.02),
            color=color(1.0, 0.85, 0.0),
        ),
    ]
    entity = SceneEntity(
        timestamp=stamp,
        frame_id=ARENA_FRAME,
        id="arena",
        cubes=[floor] + cubes,
        cylinders=cylinders,
        spheres=marks,
    )
    return SceneUpdate(entities=[entity])
