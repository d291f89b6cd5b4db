"""The Foxglove layout for rovernav's run logs and live view, built with the foxglove-sdk's
layout API from the channels' one definition (channels.py).

    python -m rovernav.runlog.layout            print it
    python -m rovernav.runlog.layout --write    write docs/foxglove-layout.json (generated: do not edit)
    python -m rovernav.runlog.layout --check    exit 1 if docs/foxglove-layout.json has drifted

In Foxglove: open run.mcap (or connect to ws://localhost:8765 for --live), then Layouts, Import
from file, docs/foxglove-layout.json.

    +---------------------------------+---------------------+
    |                                 |  camera (image)     |
    |  3D: arena, learned map, paths, +---------------------+
    |  true pose, estimate, fixes,    |  plot: position sd  |
    |  sonar echoes                   +---------------------+
    |                                 |  events (log)       |
    +---------------------------------+---------------------+
    |  frames from the rover (raw messages)                 |
    +-------------------------------------------------------+
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .channels import ARENA_FRAME, CHANNELS

LAYOUT_FILE = Path(__file__).resolve().parents[3] / "docs" / "foxglove-layout.json"

# What each 3D topic looks like: colours as in the summary picture and the video.
_POSE_COLOURS = {"/sim/true_pose": "#20c020ff", "/rover/estimate": "#ffc800ff", "/camera/fix": "#4080ffff"}
_PATH_COLOURS = {"/plan/path": ("#ff00ffff", "#ff00ffff"), "/rover/driven_path": ("#20c020ff", "#20c020ff")}


def build_layout():
    import foxglove.layouts as fl

    topics = {}
    for c in CHANNELS:
        if c.schema == "foxglove.PoseInFrame":
            topics[c.topic] = fl.BaseRendererPoseTopicSettings(
                visible=True, type="arrow", arrow_scale=(0.12, 0.02, 0.02), color=_POSE_COLOURS[c.topic]
            )
        elif c.schema == "foxglove.PosesInFrame":
            colour = _PATH_COLOURS[c.topic]
            topics[c.topic] = fl.BaseRendererPosesTopicSettings(
                visible=True, type="line", line_width=0.01, gradient=colour
            )
        elif c.schema == "foxglove.Grid":
            topics[c.topic] = fl.BaseRendererGridTopicSettings(
                visible=True,
                color_mode="gradient",
                color_field="occupied_pct",
                gradient=("#ffffff00", "#202020ff"),
                min_value=0.0,
                max_value=100.0,
                draw_behind=True,
            )
        elif c.schema == "foxglove.SceneUpdate":
            topics[c.topic] = fl.BaseRendererSceneUpdateTopicSettings(visible=True)
    three_d = fl.ThreeDeePanel(
        title="arena", config=fl.ThreeDeeConfig(follow_tf=ARENA_FRAME, fixed_frame=ARENA_FRAME, topics=topics)
    )
    image = fl.ImagePanel(
        title="camera", config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic="/camera/image"))
    )
    plot = fl.PlotPanel(
        title="the rover's position sd (mm)",
        config=fl.PlotConfig(
            paths=[fl.PlotSeries(value="/rover/status.sd_x_mm"), fl.PlotSeries(value="/rover/status.sd_y_mm")]
        ),
    )
    events = fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render="/events"))
    frames = fl.RawMessagesPanel(
        title="frames from the rover", config=fl.RawMessagesConfig(topic_path="/link/rover_to_host")
    )
    right = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(proportion=2, content=image),
            fl.SplitItem(proportion=1, content=plot),
            fl.SplitItem(proportion=1, content=events),
        ],
    )
    top = fl.SplitContainer(
        direction="row", items=[fl.SplitItem(proportion=2, content=three_d), fl.SplitItem(proportion=1, content=right)]
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="column",
            items=[fl.SplitItem(proportion=3, content=top), fl.SplitItem(proportion=1, content=frames)],
        )
    )


def layout_text() -> str:
    data = json.loads(build_layout().to_json())
    data = {"_generated": "by python -m rovernav.runlog.layout --write from host/rovernav/runlog/; do not edit", **data}
    return json.dumps(data, indent=2, sort_keys=True) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rovernav.runlog.layout", description=__doc__.split("\n\n")[0])
    g = p.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help=f"write {LAYOUT_FILE.name} into docs/")
    g.add_argument("--check", action="store_true", help="exit 1 if the file in docs/ differs from what this builds")
    args = p.parse_args(argv)
    text = layout_text()
    if args.write:
        LAYOUT_FILE.write_text(text)
        print(f"wrote {LAYOUT_FILE}")
    elif args.check:
        if not LAYOUT_FILE.exists() or LAYOUT_FILE.read_text() != text:
            print(f"{LAYOUT_FILE} has drifted: run python -m rovernav.runlog.layout --write", file=sys.stderr)
            return 1
        print(f"{LAYOUT_FILE.name} matches the channels")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
