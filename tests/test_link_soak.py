"""`rovernav link-check --soak` (rovernav.link.soak) against the rover's firmware core, in simulated
time, on a line that carries 57,600 baud and loses a known share of bytes or frames (seeded): the
loss it reports is the loss the line made, the paths load, the advice shows past its threshold and
not below it; and the command line, in real time against the core on a thread.
"""

from __future__ import annotations

import json
import random
import threading
import time

import pytest
from tests.core_transport import CoreTransport

from rovernav.cli import main
from rovernav.cores import NativeCore
from rovernav.link import messages_gen as mg
from rovernav.link import soak as sk
from rovernav.link.errors import LinkClosed
from rovernav.link.link import Link
from rovernav.link.transport import PipeTransport

KEY = bytes(range(7, 23))
BYTES_PER_STEP = 58  # 57,600 baud 8N1 is 5,760 bytes a second: 58 in the core's 10 ms step


class Loss:
    """One direction of the line: drops each byte with probability `byte_loss`, or each whole
    frame with probability `frame_loss` (seeded), and counts the frames it broke: a frame is
    broken when a byte of it is lost, or the 0x00 that ends the frame before it (the two then run
    together and fail their CRC)."""

    def __init__(self, byte_loss: float = 0.0, frame_loss: float = 0.0, seed: int = 1):
        self.byte_loss, self.frame_loss, self.rng = byte_loss, frame_loss, random.Random(seed)
        self.on = False  # switched on after the HELLO
        self.frames = self.broken = 0
        self._partial = b""
        self._lost_delimiter = False

    def apply(self, data: bytes) -> bytes:
        data = self._partial + data
        cut = data.rfind(b"\x00") + 1
        self._partial, data = data[cut:], data[:cut]
        if not self.on:
            return data
        out = bytearray()
        start = 0
        while start < len(data):
            end = data.index(0, start) + 1
            frame = data[start:end]
            start = end
            self.frames += 1
            if self.frame_loss and self.rng.random() < self.frame_loss:
                self.broken += 1
                self._lost_delimiter = False  # the whole frame gone: the one before stays whole
                continue
            kept = bytes(b for b in frame if not (self.byte_loss and self.rng.random() < self.byte_loss))
            self.broken += len(kept) < len(frame) or self._lost_delimiter
            self._lost_delimiter = not kept.endswith(b"\x00")
            out += kept
        return bytes(out)

    @property
    def share(self) -> float:
        return self.broken / self.frames


class Line(CoreTransport):
    """The rover core behind a 57,600-baud line that may lose bytes or frames each way."""

    def __init__(self, core: NativeCore, to_rover: Loss | None = None, to_host: Loss | None = None):
        super().__init__(core)
        self.loss_to_rover, self.loss_to_host = to_rover or Loss(), to_host or Loss()

    def lose(self) -> None:
        self.loss_to_rover.on = self.loss_to_host.on = True

    def run_ms(self, ms: int) -> None:
        for _ in range(max(1, ms // 10)):
            chunk, self.to_rover = self.to_rover[:BYTES_PER_STEP], self.to_rover[BYTES_PER_STEP:]
            out = self.core.step(self.t_ms, gyro_rate_mdps=0, rx=chunk)
            self.from_rover += self.loss_to_host.apply(out.tx)
            self.t_ms += 10

    def _write(self, data: bytes) -> None:
        super()._write(self.loss_to_rover.apply(data))

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        for _ in range(max(1, round((timeout_s or 0.0) * 100))):  # step until something comes
            if self.from_rover:
                break
            self.run_ms(10)
        data, self.from_rover = self.from_rover[:max_bytes], self.from_rover[max_bytes:]
        return data


def _soak(
    seconds: float, to_rover: Loss | None = None, to_host: Loss | None = None, key: bytes | None = None, **kwargs
) -> tuple[sk.Soak, Line]:
    line = Line(NativeCore(boot_id=11, key=key), to_rover, to_host)
    link = Link(line, key=key)
    link.handshake(boot_id=5)
    line.lose()
    soak = sk.Soak(link, clock=line.clock, poll_s=0.0, host_boot_id=5, **kwargs)
    return soak.run(seconds), line


def _lost(soak: sk.Soak, way: str) -> float:
    return soak.summary()[way]["lost_share"]


# ------------------------------------------------------------------ a clean line


@pytest.mark.parametrize("key", [None, KEY], ids=["unsigned", "signed"])
def test_a_clean_line_loses_nothing_loads_every_path_and_answers_every_probe(key):
    soak, line = _soak(30.0, key=key)
    s = soak.summary()
    assert s["seconds_run"] == pytest.approx(30.0, abs=0.05) and s["ended_by"] is None
    assert s["signed"] is (key is not None)
    for way in sk.WAYS:
        assert s[way]["lost_share"] == 0.0 and s[way]["frames_sent"] > 250, s[way]
    assert s["host_to_rover"]["rover_received_broken"] == 0
    rt = s["round_trip_s"]
    assert rt["sent"] == pytest.approx(30 * sk.PROBE_HZ, abs=2) and rt["unanswered"] == 0
    assert 0.0 < rt["median"] <= rt["p99"] <= 0.05  # a step or two of the core
    p = s["path_load_s"]
    assert p["completed"] == p["started"] >= 5 and p["chunks_sent_again"] == 0 and p["given_up"] == 0
    assert 0.0 < p["median"] <= p["worst"] < 0.2  # four chunks on a 57,600-baud line
    assert s["verdict"] == "ok" and s["advice"] is None
    assert line.core.probe().state == mg.RoverState.IDLE  # loaded, never started
    assert line.core.probe().waypoint_count == sk.PATH_WAYPOINTS
    # Signed frames are 12 bytes longer, so the thresholds are lower.
    assert s["host_to_rover"]["mean_frame_bytes"] > (24 if key else 12)


# ------------------------------------------------------------------ loss as injected


@pytest.mark.parametrize("frame_loss, seed", [(0.02, 1), (0.08, 2), (0.2, 3)])
def test_the_frame_loss_reported_is_the_frame_loss_injected_each_way(frame_loss, seed):
    soak, line = _soak(120.0, Loss(frame_loss=frame_loss, seed=seed), Loss(frame_loss=frame_loss, seed=seed + 100))
    for way, made in (("host_to_rover", line.loss_to_rover), ("rover_to_host", line.loss_to_host)):
        assert made.share == pytest.approx(frame_loss, abs=0.25 * frame_loss + 0.005)  # the line did as asked
        assert _lost(soak, way) == pytest.approx(made.share, abs=0.1 * made.share + 0.005), way
    assert soak.summary()["path_load_s"]["completed"] >= 15


@pytest.mark.parametrize("key", [None, KEY], ids=["unsigned", "signed"])
@pytest.mark.parametrize("byte_loss", [0.005, 0.02])
def test_the_frame_loss_reported_under_byte_loss_is_what_the_line_broke_and_gives_back_the_byte_loss(byte_loss, key):
    soak, line = _soak(120.0, Loss(byte_loss=byte_loss, seed=4), Loss(byte_loss=byte_loss, seed=5), key=key)
    s = soak.summary()
    for way, made in (("host_to_rover", line.loss_to_rover), ("rover_to_host", line.loss_to_host)):
        assert s[way]["lost_share"] == pytest.approx(made.share, abs=0.1 * made.share + 0.005), way
        # The byte loss that explains the frames lost, from their lengths, is the byte loss made.
        assert s[way]["byte_damage_equivalent"] == pytest.approx(byte_loss, rel=0.3), way
    assert s["host_to_rover"]["rover_received_broken"] > 0  # broken frames reach the rover's counters
    assert s["path_load_s"]["completed"] >= 15 and s["path_load_s"]["given_up"] == 0
    assert s["round_trip_s"]["unanswered"] > 0


def test_the_path_loads_at_heavy_loss_and_takes_longer():
    clean, _ = _soak(60.0)
    lossy, _ = _soak(60.0, Loss(frame_loss=0.2, seed=6), Loss(frame_loss=0.2, seed=7))
    c, p = clean.summary()["path_load_s"], lossy.summary()["path_load_s"]
    assert p["completed"] >= 8 and p["given_up"] == 0 and p["chunks_sent_again"] > 0
    assert p["worst"] > c["worst"] and p["worst"] >= sk.PATH_RESEND_S  # at least one chunk waited its resend


# ------------------------------------------------------------------ the advice


def test_the_thresholds_follow_from_byte_loss_and_frame_length():
    # One frame of L bytes arrives at byte damage p with probability (1-p)^(L+1).
    assert sk.frame_loss_at(0.01, {12: 1}, received=False) == pytest.approx(1 - 0.99**13)
    # Frames received: the lost ones are unseen; the longer ones were lost more often.
    sent = {12: 100, 52: 100}
    keep = {n: 0.95 ** (n + 1) for n in sent}
    received = {n: sent[n] * keep[n] for n in sent}
    assert sk.frame_loss_at(0.05, received, received=True) == pytest.approx(sk.frame_loss_at(0.05, sent, False))
    assert sk.byte_damage_for(sk.frame_loss_at(0.03, sent, False), sent, False) == pytest.approx(0.03)
    t = sk.typical_thresholds()
    assert t["HEARTBEAT"][0] == 16 and 0.16 < t["HEARTBEAT"][1] < 0.18 and 0.55 < t["HEARTBEAT"][2] < 0.61
    assert t["STATUS"][1] > t["HEARTBEAT"][1]  # longer frames are lost more often
    assert all(a[1] > b[1] for a, b in zip(sk.typical_thresholds(signed=True).values(), t.values()))


@pytest.mark.parametrize("byte_loss, verdict", [(0.0, "ok"), (0.004, "ok"), (0.025, "beyond"), (0.08, "failing")])
def test_the_advice_shows_past_the_threshold_and_not_below_it(byte_loss, verdict):
    soak, _ = _soak(60.0, Loss(byte_loss=byte_loss, seed=8), Loss(byte_loss=byte_loss, seed=9))
    s = soak.summary()
    lines = soak.report_lines()
    advice = [line for line in lines if line.startswith("advice:")]
    assert s["verdict"] == verdict, lines
    if verdict == "ok":
        assert not advice and s["advice"] is None and lines[-1].startswith("verdict: within")
        for way in sk.WAYS:
            assert s[way]["lost_share"] <= s[way]["tolerated_lost_share"]
    else:
        assert len(advice) == 1 and advice[0] == s["advice"] and "move the radio" in advice[0]
        assert any(s[w]["lost_share"] > s[w]["tolerated_lost_share"] for w in sk.WAYS)
        if verdict == "failing":
            assert "at which missions fail" in advice[0]
            assert any(s[w]["lost_share"] > s[w]["failing_lost_share"] for w in sk.WAYS)
        else:
            assert "beyond the" in advice[0] and "shown to tolerate" in advice[0]


def test_the_advice_is_for_one_way_when_only_that_way_loses():
    soak, _ = _soak(60.0, to_host=Loss(frame_loss=0.93, seed=10))
    s = soak.summary()
    assert s["host_to_rover"]["lost_share"] < 0.01
    assert s["verdict"] == "failing" and "rover -> host" in s["advice"] and "host -> rover" not in s["advice"]


# ------------------------------------------------------------------ what a soak does not do


def test_no_path_is_sent_to_a_rover_running_a_mission():
    line = Line(NativeCore(boot_id=11))
    link = Link(line)
    link.handshake(boot_id=5)
    soak = sk.Soak(link, clock=line.clock, poll_s=0.0, host_boot_id=5)
    soak.run(2.0)  # the soak's first path is loaded ...
    assert soak.summary()["path_load_s"]["completed"] == 1 and line.core.probe().state == mg.RoverState.IDLE
    link.send(mg.Fix(x_mm=300, y_mm=300, heading_cdeg=0, age_ms=0, sd_mm=10, frame_seq=1))
    line.run_ms(100)
    link.send(mg.Start(path_id=soak._path_id(0)))  # ... and someone starts a mission on it
    line.run_ms(500)
    assert line.core.probe().state != mg.RoverState.IDLE
    before = soak.loads_started
    soak.run(12.0)
    s = soak.summary()["path_load_s"]
    assert soak.loads_started == before and s["skipped_mission_running"] >= 2
    assert any("running a mission" in line for line in soak.report_lines())


def test_ctrl_c_ends_the_soak_early_with_its_figures():
    line = Line(NativeCore(boot_id=11))
    link = Link(line)
    link.handshake(boot_id=5)
    read = line._read

    def interrupted(max_bytes, timeout_s):
        if line.t_ms > 8000:
            raise KeyboardInterrupt
        return read(max_bytes, timeout_s)

    line._read = interrupted
    soak = sk.Soak(link, clock=line.clock, poll_s=0.0).run(60.0)
    s = soak.summary()
    assert s["ended_by"] == "Ctrl-C" and 6.0 < s["seconds_run"] < 9.0
    assert s["host_to_rover"]["frames_sent"] > 50 and s["path_load_s"]["completed"] >= 1
    assert "ended early (Ctrl-C)" in soak.report_lines()[0]


def test_progress_lines_every_few_seconds():
    seen: list[str] = []
    soak, _ = _soak(21.0, progress=seen.append, progress_s=5.0)
    assert len(seen) == 4 and seen[0].startswith("soak 5/21 s: frames through: to rover")


def test_a_rover_that_restarts_mid_soak_is_followed():
    soak, line = _soak(5.0)
    line.core.close()
    line.core = NativeCore(boot_id=99)  # a reset: a new boot id, counters from 0
    soak.run(10.0)
    s = soak.summary()
    assert s["rover"]["restarts"] == 1 and s["rover"]["boot_id"] == 99
    assert s["host_to_rover"]["lost_share"] < 0.02 and s["rover_to_host"]["lost_share"] < 0.02
    assert any("RESTARTED" in line.upper() for line in soak.report_lines())
    assert line.core.probe().flags & mg.StatusFlag.SCHEMA_OK  # told who the host is again


# ------------------------------------------------------------------ the command line


class _RealTimeRover:
    """The rover core on a thread, stepped every 10 ms of wall time, behind the far end of a pipe."""

    def __init__(self, key: bytes | None = None):
        self.host_end, self.rover_end = PipeTransport.pair()
        self.core = NativeCore(boot_id=3, key=key)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        started = time.monotonic()
        step = 0
        line = b""
        while not self.stop.is_set():
            try:
                line += self.rover_end.read(4096, 0)
            except LinkClosed:
                return  # the host closed its port
            rx, line = line[:BYTES_PER_STEP], line[BYTES_PER_STEP:]  # as fast as the line brings them
            out = self.core.step(step * 10, gyro_rate_mdps=0, rx=rx)
            if out.tx:
                self.rover_end.write(out.tx)
            step += 1
            time.sleep(max(0.0, started + step * 0.01 - time.monotonic()))

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(5)


@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signed"])
def test_link_check_soak_on_the_command_line(tmp_path, monkeypatch, capsys, signed):
    key_file = tmp_path / "link.key"
    if signed:
        from rovernav.link.keys import load_key_file, write_key_file

        write_key_file(key_file)
    with _RealTimeRover(load_key_file(key_file) if signed else None) as rover:
        monkeypatch.setattr("rovernav.link.transport.open_transport", lambda spec: rover.host_end)
        out_json = tmp_path / "soak.json"
        argv = ["link-check", "--port", "loop://", "--soak", "2.5", "--json", str(out_json)]
        code = main(argv + (["--key-file", str(key_file)] if signed else []))
    out, err = capsys.readouterr()
    assert code == 0, err
    figures = json.loads(out_json.read_text())
    assert figures["signed"] is signed and figures["seconds_asked"] == 2.5
    assert figures["round_trip_s"]["answered"] >= 8 and figures["path_load_s"]["completed"] >= 1
    assert figures["host_to_rover"]["lost_share"] == 0.0 and figures["rover_to_host"]["lost_share"] == 0.0
    assert "rover says HELLO" in out and "frames lost host -> rover: 0.00 %" in out and "verdict:" in out
    assert "round trip (CONFIG probe -> NACK" in out and "32-waypoint path load: median" in out
    assert f"wrote the figures to {out_json}" in out


def test_link_check_soak_ctrl_c_prints_the_report_and_writes_the_figures(tmp_path, monkeypatch, capsys):
    with _RealTimeRover() as rover:
        read = rover.host_end._read
        started = time.monotonic()

        def interrupted(max_bytes, timeout_s):
            if time.monotonic() - started > 1.5:
                raise KeyboardInterrupt
            return read(max_bytes, timeout_s)

        monkeypatch.setattr(rover.host_end, "_read", interrupted)
        monkeypatch.setattr("rovernav.link.transport.open_transport", lambda spec: rover.host_end)
        code = main(["link-check", "--port", "loop://", "--soak", "600", "--json", str(tmp_path / "s.json")])
    out, err = capsys.readouterr()
    assert code == 130
    assert "ended early (Ctrl-C)" in out and "round trip" in out
    assert json.loads((tmp_path / "s.json").read_text())["ended_by"] == "Ctrl-C"


@pytest.mark.parametrize(
    "argv, names",
    [
        (["--soak", "nan"], "--soak"),
        (["--soak", "-5"], "--soak"),
        (["--soak", "0"], "--soak"),
        (["--soak", "inf"], "--soak"),
        (["--soak", "1e9"], "--soak"),
        (["--soak", "ten"], "--soak"),
        (["--soak", "60", "--json", "figures.txt"], "--json"),
        (["--json", "figures.json"], "--json"),
        (["--soak", "60", "--seconds", "5"], "--seconds"),
    ],
)
def test_link_check_soak_refuses_bad_input_in_one_line_with_status_2(argv, names, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(["link-check", "--port", "loop://", *argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and names in lines[0] and "Traceback" not in err, err
    assert not (tmp_path / "figures.json").exists()


def test_link_check_help_says_what_the_soak_measures(capsys):
    with pytest.raises(SystemExit):
        main(["link-check", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for phrase in (
        "rx_ok",
        "sequence numbers",
        "99th percentile",
        "NACK unknown_param",
        "No START is sent",
        "(1-p)^(L+1)",
        "1 % of bytes lost",
        "Ctrl-C",
        "--json FILE",
    ):
        assert phrase in text, phrase
