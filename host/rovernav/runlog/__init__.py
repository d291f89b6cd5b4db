"""Run logs: every run as an MCAP file that Foxglove opens, the same channels live, and replay.

    writer.py   RunLog: the channels (Foxglove's well-known schemas where one fits, JSON where
                the data is ours), written to run.mcap and, with --live, served over Foxglove's
                WebSocket protocol on localhost
    replay.py   `rovernav replay LOG.mcap`: the host's mission code again against the rover
                frames a log recorded; where its decisions differ from the recorded ones
    channels.py the topics, their schemas and what each carries (one definition for the
                writer, the replay, the tests and the README's table)
"""
from .channels import CHANNELS, LOG_FORMAT, LOG_VERSION
from .writer import RecordingTransport, RunLog

__all__ = ["CHANNELS", "LOG_FORMAT", "LOG_VERSION", "RecordingTransport", "RunLog"]
