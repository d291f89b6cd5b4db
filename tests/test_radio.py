"""The simulated radio as users set it (rovernav/radio.py, modelled by sim/channel.py): loss and bit errors, independent or in
Gilbert-Elliott bursts shared by both directions, per-frame jitter that keeps order, a
half-duplex medium where both ends' bytes collide, frames counted by message kind; the flags and
the [radio] table that set it, and what a run says about it (report.json, the run log)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rovernav.cli import main
from rovernav.config import ConfigError, config_from_dict
from rovernav.errors import InputError
from rovernav.link import messages_gen as mg
from rovernav.link.framing import encode_frame
from rovernav.radio import ChannelConfig, radio_config
from rovernav.sim.channel import BurstProcess, Channel, channel_pair, frame_kind

FIG48 = "seed-fig4-8-unknown-obstacle"
BYTE_S = 1 / 5760  # one byte's time on the air at 57,600 baud 8N1


def _stream(n: int) -> bytes:
    """n bytes with no 0x00 among them (no frame ends: only bytes are counted)."""
    return bytes(range(1, 256)) * (n // 255) + bytes(range(1, 1 + n % 255))


def _state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


# ---------------------------------------------------------------- loss and bit errors


def test_the_defaults_draw_nothing_from_the_generator():
    rng = np.random.default_rng(7)
    before = _state(rng)
    to_rover, to_host = channel_pair(ChannelConfig(), rng)
    frame = encode_frame(mg.Heartbeat(), 1)
    for i in range(100):
        to_rover.write(frame, i * 0.01)
        to_host.write(frame * 2, i * 0.01)
        to_rover.receive(i * 0.01)
        to_host.receive(i * 0.01)
    to_rover.receive(5.0)
    to_host.receive(5.0)
    assert _state(rng) == before
    assert to_rover.counters()["frames"] == {"heartbeat": {"sent": 100, "damaged": 0}}
    assert to_host.counters()["frames_sent"] == 200 and to_host.bytes_delivered == to_host.bytes_sent


def test_independent_loss_and_bit_errors_come_out_at_their_long_run_means():
    n = 300_000
    ch = Channel(radio_config(loss_pct=5.0, ber_pct=2.0), np.random.default_rng(11))
    data = _stream(n)
    ch.write(data, 0.0)
    got = ch.receive(n * BYTE_S + 1.0)
    assert ch.bytes_lost / n == pytest.approx(0.05, abs=0.003)  # binomial sd 0.0004
    assert ch.bytes_corrupted / n == pytest.approx(0.02, abs=0.002)  # of the bytes SENT, not those through
    assert len(got) == n - ch.bytes_lost and ch.lost_by["noise"] == ch.bytes_lost
    assert ch.bytes_in_bursts == 0


def test_bursts_fall_at_the_mean_length_and_share_set():
    proc = BurstProcess(mean_s=0.2, share=0.1, rng=np.random.default_rng(3))
    view = proc.view()
    horizon = 20_000.0  # some 10,000 bursts
    t, lengths, start, was_bad = 0.0, [], None, False
    while t < horizon:  # walk the switches one by one
        bad = view.bad(t)
        if bad and not was_bad:
            start = t
        elif was_bad and not bad:
            lengths.append(t - start)
        was_bad = bad
        t = view._next  # the next switch
    st = proc.stats(horizon)
    assert st["share_measured"] == pytest.approx(0.1, rel=0.05)
    assert st["burst_time_s"] / st["bursts"] == pytest.approx(0.2, rel=0.05)
    assert np.mean(lengths) == pytest.approx(0.2, rel=0.05)
    assert np.std(lengths) / np.mean(lengths) == pytest.approx(1.0, abs=0.08)  # exponential sojourns
    assert len(proc._edges) <= 4097 + 1  # switch times every reader has passed are forgotten


def test_bursty_loss_keeps_its_long_run_mean_and_falls_only_inside_bursts():
    n = 1_000_000  # 174 s of line time: some 1,700 bursts of 10 ms
    cfg = radio_config(loss_pct=4.0, ber_pct=1.0, burst_mean_s=0.01, burst_share=0.1)
    ch = Channel(cfg, np.random.default_rng(5))
    ch.write(_stream(n), 0.0)
    ch.receive(n * BYTE_S + 1.0)
    assert ch.bytes_lost / n == pytest.approx(0.04, abs=0.006)
    assert ch.bytes_corrupted / n == pytest.approx(0.01, abs=0.002)
    # Inside bursts bytes go at loss / share: 40 %, 10 % corrupted; outside, none.
    assert ch.bytes_in_bursts / n == pytest.approx(0.1, abs=0.01)
    assert ch.bytes_lost / ch.bytes_in_bursts == pytest.approx(0.40, abs=0.01)
    assert ch.bytes_corrupted / ch.bytes_in_bursts == pytest.approx(0.10, abs=0.01)
    st = ch.bursts.stats(n * BYTE_S)
    assert st["share_measured"] == pytest.approx(ch.bytes_in_bursts / n, abs=0.002)
    assert st["burst_time_s"] / st["bursts"] == pytest.approx(0.01, rel=0.1)


def test_losses_come_in_runs_with_bursts_and_alone_without():
    def runs_of_loss(cfg) -> float:
        """The mean length of runs of lost bytes (1 / (1 - loss) for independent losses)."""
        ch = Channel(cfg, np.random.default_rng(2))
        n = 100_000
        ch.write(bytes(n), 0.0)  # every byte a delimiter: each counts as its own (empty) frame
        lost = []
        orig = ch._air

        def air(t, byte, collided):
            before = ch.bytes_lost
            orig(t, byte, collided)
            lost.append(ch.bytes_lost > before)

        ch._air = air
        ch.receive(n * BYTE_S + 1.0)
        x = np.array(lost)
        starts = np.count_nonzero(x[1:] & ~x[:-1]) + x[0]
        return x.sum() / starts

    assert runs_of_loss(radio_config(loss_pct=5.0)) == pytest.approx(1 / 0.95, abs=0.05)
    assert runs_of_loss(radio_config(loss_pct=5.0, burst_mean_s=0.02, burst_share=0.1)) > 1.8  # 50 % in a burst


def test_both_directions_read_one_burst_process():
    cfg = radio_config(loss_pct=10.0, burst_mean_s=0.05, burst_share=0.2)
    to_rover, to_host = channel_pair(cfg, np.random.default_rng(9))
    assert to_rover.bursts is to_host.bursts
    for i in range(3000):  # the same traffic both ways, as a reader of the host, then the rover
        t = i * 0.01
        to_rover.write(_stream(40), t)
        to_host.write(_stream(40), t)
        to_host.receive(t)
        to_rover.receive(t)
    assert to_rover.bytes_in_bursts == to_host.bytes_in_bursts > 0  # the same bytes fell in bursts
    assert to_rover.bytes_lost != to_host.bytes_lost  # each drew its own losses


# ---------------------------------------------------------------- jitter


def test_jitter_adds_its_mean_delay_per_frame():
    ch = Channel(radio_config(jitter_ms=30.0), np.random.default_rng(8))
    for i in range(500):  # a second apart: no frame waits for another
        ch.write(encode_frame(mg.Heartbeat(), i % 256), float(i))
    ch.advance(600.0)
    arrivals = [a for a, _byte in ch._in_flight]
    n = len(encode_frame(mg.Heartbeat(), 0))  # bytes a frame
    extra = np.array([arrivals[i * n] - i - BYTE_S - 0.015 for i in range(500)])
    assert extra.min() >= -1e-9
    assert extra.mean() == pytest.approx(0.030, abs=0.004)  # sd of the mean: 1.3 ms
    assert extra.std() == pytest.approx(0.030, rel=0.15)  # exponential
    # Within a frame the bytes keep the line's spacing.
    assert arrivals[11] - arrivals[0] == pytest.approx(11 * BYTE_S)


def test_jitter_never_reorders_bytes():
    ch = Channel(radio_config(jitter_ms=30.0), np.random.default_rng(4))
    sent, arrivals = bytearray(), []
    for i in range(400):  # every 20 ms: a late frame holds up those behind it
        frame = encode_frame(mg.Heartbeat(), i % 256)
        ch.write(frame, i * 0.02)
        sent += frame
    got, t = bytearray(), 0.0
    while t < 400 * 0.02 + 5.0:
        data = ch.receive(t)
        got += data
        arrivals += [t] * len(data)
        t = round(t + 0.001, 6)
    assert bytes(got) == bytes(sent)  # all of it, in order
    assert all(a <= b for a, b in zip(arrivals, arrivals[1:]))
    n = len(encode_frame(mg.Heartbeat(), 0))  # bytes a frame
    firsts = np.array([arrivals[i * n] - i * 0.02 for i in range(400)])
    assert firsts.min() >= 0.015 + BYTE_S - 0.001
    assert firsts.mean() - 0.015 > 0.030  # the waits behind late frames add to the jitter


# ---------------------------------------------------------------- half duplex


def _medium_pair():
    return channel_pair(radio_config(half_duplex=True), np.random.default_rng(0))


def test_half_duplex_frames_sent_at_once_collide_both_ways():
    a, b = _medium_pair()
    fa, fb = encode_frame(mg.Fix(), 1), encode_frame(mg.Status(), 2)
    a.write(fa, 0.0)
    b.write(fb, 0.0)
    got_a, got_b = a.receive(1.0), b.receive(1.0)
    # A's 18 bytes all overlap B's first 18; B's last 34 go through.
    assert got_a == b"" and a.bytes_lost == a.lost_by["collision"] == len(fa)
    assert got_b == fb[len(fa) :] and b.bytes_lost == len(fa)
    assert a.counters()["frames"] == {"fix": {"sent": 1, "damaged": 1}}
    assert b.counters()["frames"] == {"status": {"sent": 1, "damaged": 1}}


def test_half_duplex_one_end_alone_or_in_turn_loses_nothing():
    a, b = _medium_pair()
    f = encode_frame(mg.Status(), 3)
    for i in range(50):
        a.write(f, i * 0.1)  # alone
    for i in range(50):
        b.write(f, 10.0 + i * 0.1)  # then the other end, alone
        a.write(f, 10.0 + i * 0.1 + len(f) * BYTE_S + 1e-7)  # and this one right after each: no overlap
    a.receive(30.0)
    b.receive(30.0)
    assert a.bytes_lost == b.bytes_lost == 0
    assert a.counters()["frames"]["status"] == {"sent": 100, "damaged": 0}


def test_half_duplex_a_partial_overlap_costs_the_overlapping_bytes_of_each():
    a, b = _medium_pair()
    a.write(_stream(20), 0.0)
    b.write(_stream(5), 10.5 * BYTE_S)  # B starts halfway through A's 11th byte
    got_a, got_b = a.receive(1.0), b.receive(1.0)
    assert b.bytes_lost == 5 and got_b == b""
    assert a.bytes_lost == 6 and got_a == _stream(20)[:10] + _stream(20)[16:]  # A's 11th to 16th overlap


def test_full_duplex_frames_sent_at_once_both_arrive():
    a, b = channel_pair(ChannelConfig(), np.random.default_rng(0))
    a.write(encode_frame(mg.Fix(), 1), 0.0)
    b.write(encode_frame(mg.Status(), 2), 0.0)
    assert len(a.receive(1.0)) == 18 and len(b.receive(1.0)) == 52


# ---------------------------------------------------------------- frames by kind


def test_frames_are_counted_by_kind_and_damage_by_any_byte_lost():
    frames = [
        encode_frame(mg.Hello(), 0),
        encode_frame(mg.Fix(), 1),
        encode_frame(mg.Fix(), 2),
        encode_frame(mg.Heartbeat(), 3),
        encode_frame(mg.Fix(), 4),
        encode_frame(mg.Stop(), 5),
    ]
    # The second FIX goes out during an outage; one frame is written in two pieces; a stray
    # delimiter (an empty frame) and some noise ending in one.
    ch = Channel(ChannelConfig(), np.random.default_rng(0), outages=[(1.0, 1.5)])
    ch.write(frames[0], 0.0)
    ch.write(frames[1][:5], 0.5)
    ch.write(frames[1][5:], 0.5)
    ch.write(frames[2], 1.2)
    ch.write(b"\x00", 2.0)
    ch.write(b"\x07\x99\x07\x00", 2.1)  # COBS says 7 bytes follow: not a frame
    ch.write(frames[3] + frames[4] + frames[5], 3.0)
    ch.receive(10.0)
    c = ch.counters()
    assert c["frames"] == {
        "hello": {"sent": 1, "damaged": 0},
        "fix": {"sent": 3, "damaged": 1},
        "heartbeat": {"sent": 1, "damaged": 0},
        "stop": {"sent": 1, "damaged": 0},
        "malformed": {"sent": 1, "damaged": 0},
    }
    assert c["frames_sent"] == 7 and c["frames_damaged"] == 1
    assert c["bytes_lost"] == c["bytes_lost_by"]["outage"] == len(frames[2])


def test_a_frame_with_a_flipped_bit_is_damaged_and_kinds_come_from_the_msg_id():
    ch = Channel(ChannelConfig(bit_error=1.0), np.random.default_rng(0))
    ch.write(encode_frame(mg.Obstacle(), 9), 0.0)
    ch.receive(1.0)
    assert ch.counters()["frames"] == {"obstacle": {"sent": 1, "damaged": 1}}
    assert frame_kind(encode_frame(mg.Status(), 1)[:-1]) == "status"
    assert frame_kind(bytes([4, 1, 0x7E, 1])) == "unknown"  # msg id 0x7E: none of ours
    assert frame_kind(b"\x02\x01") == "malformed"  # too short for a header


# ---------------------------------------------------------------- what users may set


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"loss_pct": -1.0}, "--radio-loss"),
        ({"loss_pct": 100.5}, "--radio-loss"),
        ({"ber_pct": math.nan}, "--radio-ber"),
        ({"jitter_ms": math.inf}, "--radio-jitter-ms"),
        ({"burst_mean_s": 0.5, "burst_share": 1.0}, "--radio-burst SHARE"),
        ({"burst_mean_s": 0.5, "burst_share": 0.0}, "--radio-burst SHARE"),
        ({"burst_mean_s": 0.0, "burst_share": 0.5}, "--radio-burst MEAN_S"),
        ({"loss_pct": 20.0, "burst_mean_s": 0.5, "burst_share": 0.1}, "200 % there"),
        ({"loss_pct": 6.0, "ber_pct": 5.0, "burst_mean_s": 0.5, "burst_share": 0.1}, "110 % there"),
        ({"loss_pct": 60.0, "ber_pct": 50.0}, "cannot pass 100 %"),
    ],
)
def test_radio_settings_out_of_range_are_refused_in_one_line(kw, words):
    with pytest.raises(InputError) as exc:
        radio_config(**kw)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_the_limits_themselves_are_taken():
    cfg = radio_config(loss_pct=10.0, burst_mean_s=0.5, burst_share=0.1)  # 100 % inside bursts
    assert cfg.bursts and cfg.byte_loss == pytest.approx(0.1)
    assert radio_config(loss_pct=100.0).byte_loss == 1.0
    assert not radio_config(burst_mean_s=0.5, burst_share=0.1).bursts  # bursts of nothing: no process


@pytest.mark.parametrize(
    "table, words",
    [
        ({"loss_pct": 101}, "[radio] loss_pct"),
        ({"loss_pct": "5"}, "[radio] loss_pct"),
        ({"burst_mean_s": 0.5}, "[radio] burst_share"),
        (
            {"loss_pct": 5, "burst_mean_s": 0.5, "burst_share": 0.02},
            "[radio] loss_pct 5 % with r.toml: [radio] burst_share",
        ),
        ({"half_duplex": 1}, "[radio] half_duplex"),
        ({"loss": 1}, "no key 'loss'"),
    ],
)
def test_a_bad_radio_table_names_its_key(table, words):
    with pytest.raises(ConfigError) as exc:
        config_from_dict({"radio": table}, where="r.toml: ")
    assert words in str(exc.value) and str(exc.value).startswith("r.toml: ")


@pytest.mark.parametrize(
    "flags",
    [
        ["--radio-loss", "-1"],
        ["--radio-loss", "101"],
        ["--radio-loss", "nan"],
        ["--radio-ber", "1e9"],
        ["--radio-burst", "0.5:1"],
        ["--radio-burst", "0.5:0"],
        ["--radio-burst", "0.5"],
        ["--radio-burst", "inf:0.1"],
        ["--radio-jitter-ms", "-2"],
        ["--radio-loss", "20", "--radio-burst", "0.5:0.1"],
        ["--radio-loss", "70", "--radio-ber", "40"],
    ],
)
@pytest.mark.parametrize("command", ["sim", "trials"])
def test_out_of_range_radio_flags_end_in_one_line_and_status_2(tmp_path, capsys, flags, command):
    where = [FIG48] if command == "sim" else [str(tmp_path)]
    try:
        code = main([command, *where, "--out", str(tmp_path / "out"), *flags])
    except SystemExit as exc:  # refused by the parser
        code = exc.code
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith(f"rovernav {command}: ") and "\n" not in err and "Traceback" not in err
    assert "--radio-" in err
    assert not (tmp_path / "out" / "report.json").exists()


def test_the_help_says_each_radio_flag_with_its_units_and_default(capsys):
    with pytest.raises(SystemExit):
        main(["sim", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for words in (
        "--radio-loss PCT",
        "in percent, 0 to 100 (default 0)",
        "--radio-burst MEAN_S:SHARE",
        "off: none (the default)",
        "--radio-jitter-ms MS",
        "in milliseconds",
        "--radio-half-duplex",
        "Default off",
        "[radio] table",
    ):
        assert words in text, words


# ---------------------------------------------------------------- in a run


def test_a_short_run_with_the_radio_flags_reports_and_logs_what_the_radio_did(tmp_path, capsys):
    (tmp_path / "c.toml").write_text(
        "[radio]\nloss_pct = 5\nburst_mean_s = 0.3\nburst_share = 0.25\nhalf_duplex = true\n"
    )
    out = tmp_path / "run"
    code = main(
        [
            "sim",
            FIG48,
            "--no-video",
            "--quiet",
            "--max-time",
            "4",
            "--out",
            str(out),
            "--config",
            str(tmp_path / "c.toml"),
            "--radio-loss",
            "2",
            "--radio-ber",
            "1",
            "--radio-jitter-ms",
            "8",
            "--no-radio-half-duplex",
        ]
    )
    printed = capsys.readouterr().out
    assert code == 1  # 4 s is not enough to arrive
    assert "radio (loss 2 %, BER 1 %, bursts 0.3 s, 25 % of the time, jitter 8 ms)" in printed
    report = json.loads((out / "report.json").read_text())
    radio = report["radio"]
    st = radio["settings"]  # the flags over the file, the file over the defaults
    assert (st["loss_pct"], st["ber_pct"], st["jitter_ms"], st["half_duplex"]) == (2.0, 1.0, 8.0, False)
    assert st["burst"]["mean_s"] == 0.3 and st["burst"]["share"] == 0.25 and st["burst"]["loss_in_burst_pct"] == 8.0
    assert radio["bursts"]["bursts"] >= 1
    for way, kinds in (("to_rover", {"hello", "config"}), ("to_host", {"hello", "status"})):
        c = radio[way]
        assert kinds <= set(c["frames"]) and c["frames_sent"] == sum(k["sent"] for k in c["frames"].values())
        assert c["bytes_sent"] == report["link"][way]["bytes_sent"] > 0
        assert c["bytes_lost"] == c["bytes_lost_by"]["noise"]
    # The run log: /sim/radio at 1 Hz and at the end, the last with the report's counts.
    from mcap.reader import make_reader

    with open(out / "run.mcap", "rb") as f:
        logged = [json.loads(m.data) for _s, _c, m in make_reader(f).iter_messages(topics=["/sim/radio"])]
    assert len(logged) >= 4 and [r["t_s"] for r in logged] == sorted(r["t_s"] for r in logged)
    assert logged[-1]["to_host"] == radio["to_host"] and logged[-1]["to_rover"] == radio["to_rover"]
    assert logged[0]["to_host"]["bytes_sent"] <= logged[-1]["to_host"]["bytes_sent"]


def test_a_run_with_the_defaults_reports_a_radio_that_lost_nothing(tmp_path):
    out = tmp_path / "run"
    assert main(["sim", FIG48, "--no-video", "--quiet", "--no-log", "--max-time", "2", "--out", str(out)]) == 1
    radio = json.loads((out / "report.json").read_text())["radio"]
    assert radio["settings"] == ChannelConfig().settings() and radio["bursts"] is None
    assert radio["settings"]["half_duplex"] is False and radio["settings"]["burst"] is None
    for way in ("to_rover", "to_host"):
        assert radio[way]["bytes_lost"] == radio[way]["frames_damaged"] == 0 and radio[way]["frames_sent"] > 0


@pytest.mark.mission
def test_trials_carry_the_radio_settings_to_every_run_and_the_summary(tmp_path, capsys):
    arenas = tmp_path / "arenas"
    arenas.mkdir()
    (arenas / "fig.toml").write_text((Path(__file__).resolve().parents[1] / "scenarios" / f"{FIG48}.toml").read_text())
    out = tmp_path / "out"
    rc = main(
        [
            "trials",
            str(arenas),
            "--serial",
            "--max-time",
            "60",
            "--out",
            str(out),
            "--radio-loss",
            "1",
            "--radio-burst",
            "0.2:0.1",
            "--radio-jitter-ms",
            "5",
        ]
    )
    assert rc in (0, 1), capsys.readouterr().err
    summary = json.loads((out / "trials.json").read_text())
    st = summary["settings"]["radio"]
    assert (st["loss_pct"], st["burst"]["mean_s"], st["burst"]["share"], st["jitter_ms"]) == (1.0, 0.2, 0.1, 5.0)
    assert "--radio-loss 1 --radio-jitter-ms 5 --radio-burst 0.2:0.1" in summary["command"]
    assert "Radio: 57,600 baud, 15 ms latency, byte loss 1 %" in (out / "trials.md").read_text()
    run = json.loads((out / "runs" / "rovernav" / "fig-s1" / "report.json").read_text())
    assert run["radio"]["settings"] == st


# ---------------------------------------------------------------- a fleet on one radio (issue 30)


def _fleet(rovers: int, **settings):
    from rovernav.sim.channel import fleet_channels

    return fleet_channels(radio_config(**settings), np.random.default_rng(5), rovers)


def test_the_hosts_broadcast_reaches_every_rover_once_and_never_collides_with_itself():
    host, to_rovers, to_host = _fleet(3, half_duplex=True)
    f = encode_frame(mg.Fix(), 1)
    for i in range(20):
        host.write(f, i * 0.05)
    got = [c.receive(2.0) for c in to_rovers]
    assert got == [f * 20] * 3
    assert all(c.bytes_lost == 0 for c in to_rovers) and host.queued() == 0


def test_two_rovers_answering_at_once_collide_and_so_does_the_host_over_them():
    host, to_rovers, to_host = _fleet(3, half_duplex=True)
    s = encode_frame(mg.Status(), 2)
    to_host[0].write(s, 0.0)
    to_host[1].write(s, 0.0)  # both at once: both lost at the host
    assert to_host[0].receive(1.0) == b"" and to_host[1].receive(1.0) == b""
    assert to_host[0].lost_by["collision"] == to_host[1].lost_by["collision"] == len(s)
    to_host[2].write(s, 2.0)
    host.write(encode_frame(mg.Fix(), 3), 2.0)  # the host speaks over rover 3
    assert to_host[2].receive(3.0) == s[len(encode_frame(mg.Fix(), 3)) :]  # its first bytes lost
    assert all(c.receive(3.0) == b"" for c in to_rovers)  # the host's FIX lost at every rover


def test_rovers_in_turn_lose_nothing_and_each_receiver_draws_its_own_losses():
    host, to_rovers, to_host = _fleet(3, half_duplex=True)
    s = encode_frame(mg.Status(), 4)
    for i in range(30):
        for r in range(3):
            to_host[r].write(s, i * 0.1 + r * 0.025)  # slots 25 ms apart: a STATUS takes 9 ms
    assert [len(c.receive(5.0)) for c in to_host] == [30 * len(s)] * 3
    host, to_rovers, _ = _fleet(3, loss_pct=30.0)
    host.write(bytes(range(1, 201)), 0.0)
    got = [c.receive(1.0) for c in to_rovers]
    assert all(30 <= c.bytes_lost <= 90 for c in to_rovers)  # 30 % of 200, each by its own draws
    assert len({g for g in got}) == 3  # three receivers, three different sets of bytes lost


def test_a_fleet_of_one_is_a_host_and_its_rover_as_before():
    from rovernav.sim.channel import channel_pair

    config = radio_config(half_duplex=True, loss_pct=1.0)
    pair = channel_pair(config, np.random.default_rng(9))
    _host, (to_rover,), (to_host,) = _fleet(1, half_duplex=True, loss_pct=1.0)
    _host.channels[0].rng = to_host.rng = np.random.default_rng(9)  # the same draws as the pair's
    for a, b in ((pair[0], to_rover), (pair[1], to_host)):
        for i in range(40):
            a.write(encode_frame(mg.Fix(), i), i * 0.02)
            b.write(encode_frame(mg.Fix(), i), i * 0.02)
    for i in range(40):
        pair[1].write(encode_frame(mg.Status(), i), 0.005 + i * 0.02)
        to_host.write(encode_frame(mg.Status(), i), 0.005 + i * 0.02)
    assert pair[0].receive(3.0) == to_rover.receive(3.0) and pair[1].receive(3.0) == to_host.receive(3.0)
    with pytest.raises(ValueError, match="a fleet of 0 rovers"):
        _fleet(0)
