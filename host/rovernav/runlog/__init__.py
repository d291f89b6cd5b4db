"""Run logs: every run as an MCAP file that Foxglove opens, the same channels live, and replay.

writer.py   RunLog: the channels (Foxglove's well-known schemas where one fits, JSON where
            the data is ours), written to run.mcap and, with --live, served over Foxglove's
            WebSocket protocol on localhost
messages.py what the channels carry, made from the run's values: records, poses, the arena's,
            the echoes' and the map's scenes (the writer's, without its state)
replay.py   `rovernav replay LOG.mcap`: the host's mission code again against the rover
            frames a log recorded; where its decisions differ from the recorded ones
channels.py the topics, their schemas and what each carries (one definition for the
            writer, the replay, the tests and the README's table)
"""

from .channels import CHANNELS, LOG_FORMAT, LOG_VERSION


def __getattr__(name: str):
    # The writer needs numpy, OpenCV and the foxglove-sdk: loaded when a run logs, not when a
    # command only parses its flags.
    if name in ("RecordingTransport", "RunLog"):
        from . import writer

        return getattr(writer, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["CHANNELS", "LOG_FORMAT", "LOG_VERSION", "RecordingTransport", "RunLog"]
