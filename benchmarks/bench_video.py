"""Video benchmark: the annotated H.264 video of a simulated mission, its size and what encoding costs.

    python benchmarks/bench_video.py [--scenario out-and-back] [--seed 1] [--crf N] [--preset P]
                                     [--out DIR] [--without-video]

Runs the mission as `rovernav sim` does (its default options) with a `VideoWriter` as the frame
sink, then opens the video with PyAV and prints its size (MB), duration, mean bitrate, frames,
codec and pixel format, and the encoding time per frame: the median (and 99th percentile) over
the frames of the wall time of `VideoWriter.write` (BGR to YUV 4:2:0, the encode call and muxing),
and apart from it the annotation's (`VideoWriter.annotate`). libx264 works in threads of its own,
so the encode call returns before its frame is coded; the process's CPU time over the run (all
threads) is printed beside the wall time for that reason. --without-video also runs the mission
with no frame sink and prints both wall times.

Exits 1 if the out-and-back video is over 5 MB (issue 15: out-and-back at 640x480, 30 fps, in
5 MB or less); other scenarios are reported only. --crf and --preset try other x264 settings.

Here (2 cores, other jobs running), out-and-back, seed 1: 2.86 MB for 197.8 s of video (5,934
frames; 202 s simulated, 2 % of the frames dropped by the camera model), 116 kbit/s, h264 High
yuv420p; encode 1.4 ms a frame (median; 99th percentile 5.3 ms), annotate 0.6 ms; the run 23.6 s
wall with video, 7.7 s without. OpenCV's mp4v, before: 26.3 MB, the run 23-31 s wall (median of
3 interleaved runs each: mp4v 26.2 s, libx264 23.7 s, no video 8.3 s). CRF 16: 16.2 MB, exit 1.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import av

from rovernav.evaluation.report import VideoWriter
from rovernav.scenario import load_scenario
from rovernav.sim.runner import SimOptions, Simulation

LIMIT_MB = 5.0  # for out-and-back


class TimedVideoWriter(VideoWriter):
    """A VideoWriter that keeps how long each frame's annotation and encoding took."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.annotate_s: list[float] = []
        self.encode_s: list[float] = []

    def __call__(self, t_s, frame, sim):
        t0 = time.perf_counter()
        img = self.annotate(t_s, frame, sim)
        t1 = time.perf_counter()
        self.write(img)
        t2 = time.perf_counter()
        self.annotate_s.append(t1 - t0)
        self.encode_s.append(t2 - t1)


def run(scenario, seed: int, sink) -> tuple[Simulation, float, float]:
    """Simulates the mission; (simulation, wall seconds, process CPU seconds)."""
    sim = Simulation(scenario, SimOptions(seed=seed), frame_sink=sink)
    w0, c0 = time.perf_counter(), time.process_time()
    sim.run()
    return sim, time.perf_counter() - w0, time.process_time() - c0


def probe(path: Path) -> dict:
    """What the file says of itself, and the frames it decodes to."""
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        info = {
            "codec": s.codec_context.name,
            "profile": s.codec_context.profile,
            "pix_fmt": s.codec_context.pix_fmt,
            "width": s.codec_context.width,
            "height": s.codec_context.height,
            "rate": s.average_rate,
            "duration_s": float(s.duration * s.time_base) if s.duration else c.duration / 1e6,
        }
        info["frames"] = sum(1 for _ in c.decode(video=0))
    return info


def ms(values: list[float], q: float) -> float:
    return statistics.quantiles(values, n=100)[int(q) - 1] * 1000 if q < 100 else max(values) * 1000


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="out-and-back")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--crf", type=float, default=None, help=f"x264 CRF (default {VideoWriter.CRF_DEFAULT})")
    ap.add_argument("--preset", default=None, help=f"x264 preset (default {VideoWriter.PRESET_DEFAULT})")
    ap.add_argument("--out", type=Path, default=None, help="keep the video in this folder (default: a temporary one)")
    ap.add_argument(
        "--without-video", action="store_true", help="also run the mission without video, for its wall time"
    )
    args = ap.parse_args()

    scenario = load_scenario(args.scenario)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        video = TimedVideoWriter(folder / "video.mp4", SimOptions().camera_fps, crf=args.crf, preset=args.preset)
        sim, wall, cpu = run(scenario, args.seed, video)
        t0 = time.perf_counter()
        video.close()
        flush_s = time.perf_counter() - t0
        size = video.path.stat().st_size
        info = probe(video.path)
        mb = size / 1e6
        print(f"{scenario.name} (seed {args.seed}), {sim.t:.1f} s simulated, {sim.frames_rendered} frames rendered")
        print(
            f"video {video.path if args.out else 'video.mp4'}: {mb:.2f} MB, {info['duration_s']:.1f} s, "
            f"{size * 8 / info['duration_s'] / 1000:.0f} kbit/s mean, {info['frames']} frames "
            f"({video.frames} written), {info['width']}x{info['height']} at {float(info['rate']):g} fps, "
            f"{info['codec']} ({video.codec}, {info['profile']}, {info['pix_fmt']}), "
            f"crf {video.crf:g}, preset {video.preset}"
        )
        print(
            f"per frame: encode (VideoWriter.write) median {statistics.median(video.encode_s) * 1000:.2f} ms, "
            f"99th percentile {ms(video.encode_s, 99):.2f} ms; annotate median "
            f"{statistics.median(video.annotate_s) * 1000:.2f} ms; flush at close {flush_s:.2f} s"
        )
        print(f"run with video: {wall:.1f} s wall, {cpu:.1f} s CPU (all threads), {sim.t / wall:.1f}x real time")
        if args.without_video:
            sim0, wall0, cpu0 = run(scenario, args.seed, None)
            print(
                f"run without video: {wall0:.1f} s wall, {cpu0:.1f} s CPU, {sim0.t / wall0:.1f}x real time "
                f"(video adds {wall - wall0:.1f} s wall, {(wall - wall0) / max(1, video.frames) * 1000:.2f} ms a frame)"
            )
    if scenario.name == "out-and-back" and mb > LIMIT_MB:
        print(f"FAIL: {mb:.2f} MB is over {LIMIT_MB:g} MB for out-and-back", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
