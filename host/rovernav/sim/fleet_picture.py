"""A fleet's run in one picture: the arena, the shared map, every rover's track in its own
colour, its start and its site, and where a contact happened."""

from __future__ import annotations

from pathlib import Path

import cv2

from ..arena_picture import Canvas, draw_arena

#: One colour a rover (BGR): blue, orange, green, purple.
COLOURS = ((200, 90, 30), (30, 130, 240), (60, 160, 60), (160, 60, 160))


class _Shown:
    """What draw_arena reads of a run: the scenario, and a mission for the echoes."""

    def __init__(self, sim):
        self.scenario = sim.scenario
        self.mission = sim.host.missions[0]


def fleet_picture(sim, report: dict, path: Path) -> None:
    sc = sim.scenario
    canvas = Canvas(sc.arena.width_m, sc.arena.height_m, px_per_m=360)
    draw_arena(canvas, _Shown(sim), grid=sim.host.map.grid)
    img = canvas.img
    for k, track in enumerate(sim.tracks):
        colour = COLOURS[k % len(COLOURS)]
        if len(track) > 1:
            cv2.polylines(img, [canvas.pts(track)], False, colour, 1, cv2.LINE_AA)
        start, site = sim.host.missions[k].start_xy, sim.host.missions[k].target_xy
        cv2.circle(img, canvas.pt(*start), 9, colour, 2)
        cv2.drawMarker(img, canvas.pt(*site), colour, cv2.MARKER_TILTED_CROSS, 16, 2)
        cv2.putText(
            img, str(k + 1), canvas.pt(start[0] - 0.02, start[1] - 0.02), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1
        )
    if sim.crash is not None:
        cv2.drawMarker(img, canvas.pt(sim.crash["x_m"], sim.crash["y_m"]), (0, 0, 255), cv2.MARKER_CROSS, 28, 3)
    title = (
        f"{sc.name}: {report['rovers']} rovers, {report['outcome']}, {report['trips_done']} trips in "
        f"{report['mission_time_s']:.0f} s, {report['contacts']} contacts"
    )
    cv2.putText(img, title, (8, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (20, 20, 20), 1, cv2.LINE_AA)
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp.png")
    cv2.imwrite(str(tmp), img)
    tmp.replace(path)
