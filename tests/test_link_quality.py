"""The host's measure of frames through, both ways (rovernav.link.quality)."""

from __future__ import annotations

import pytest

from rovernav.link import messages_gen as mg
from rovernav.link.quality import LinkQuality


def _status(rx_ok, bad_crc=0):
    return mg.Status(rx_ok=rx_ok & 0xFFFF, rx_bad_crc=bad_crc)


def test_gaps_in_the_rovers_sequence_numbers_are_frames_lost_on_the_way_to_the_host():
    q = LinkQuality()
    for t, seq in enumerate([250, 251, 253, 254, 255, 2]):  # 252 lost, and 0 and 1 (across the wrap)
        q.on_frame(seq, t * 0.1)
    s = q.summary()["rover_to_host"]
    assert (s["frames_sent"], s["frames_arrived"]) == (8, 5)  # 251..2: eight sent, five arrived
    assert q.recent("to_host") == pytest.approx(5 / 8)


def test_a_gap_longer_than_an_outage_is_not_counted_as_loss():
    q = LinkQuality(max_gap_s=5.0)
    q.on_frame(10, 0.0)
    q.on_frame(100, 30.0)  # 30 s of silence: an outage; the numbers may have wrapped
    q.on_frame(101, 30.1)
    assert q.summary()["rover_to_host"]["frames_sent"] == 1


def test_the_rovers_rx_ok_against_the_frames_the_host_sent_is_the_rate_to_the_rover():
    q = LinkQuality()
    q.on_status(_status(65530), host_sent=100, now_s=0.0)
    q.on_status(_status(65530 + 18, bad_crc=2), host_sent=120, now_s=1.0)  # 18 of 20, across rx_ok's wrap
    s = q.summary()
    assert (s["host_to_rover"]["frames_sent"], s["host_to_rover"]["frames_arrived"]) == (20, 18)
    assert s["rover_received_broken"] == 2 and s["host_to_rover"]["success"] == 0.9
    assert "to rover 90.0 %" in q.line()


def test_a_rover_restart_starts_its_counters_again():
    q = LinkQuality()
    q.on_status(_status(5000), host_sent=10, now_s=0.0)
    q.on_frame(200, 0.0)
    q.restart()
    q.on_status(_status(3), host_sent=20, now_s=1.0)  # the restarted rover counts from 0
    q.on_frame(0, 1.0)
    assert q.summary()["host_to_rover"]["frames_sent"] == 0 and q.summary()["rover_to_host"]["frames_sent"] == 0


def test_the_recent_window_forgets_old_loss():
    q = LinkQuality(window_s=10.0)
    for i in range(10):
        q.on_frame(2 * i, i * 0.1)  # every other frame lost
    for i in range(10):
        q.on_frame(20 + i, 20 + i * 0.1)  # nothing lost, 20 s later
    assert q.recent("to_host") == 1.0 and q.summary()["rover_to_host"]["success"] < 0.7
