"""`rovernav sim --rover uno`: the Uno image in simavr, with the simulated world on its pins: the
harness's reading of the pins, the rover-core protocol, the gyro, resets and the watchdog, idle
fast-forward, whole missions and the image's detour planner within the step period. The cycle
profile is tested in test_uno_profile.py, signed frames and the owner's consent in
test_uno_signing.py.

Builds the image (tools/build_uno.py) and the harness (make -C tools/avrsim unocore) when they
are missing (conftest.py's uno_built), and skips (saying which Debian package is missing) when the
AVR toolchain or libsimavr-dev is not installed. The whole-mission tests are marked `mission`.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from rovernav.cores import uno
from rovernav.cores import uno_harness as harness
from rovernav.cores.uno import UnoCore
from rovernav.cores.uno_harness import UnoSetupError, _Regs
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder


@pytest.fixture(scope="module")
def built(uno_built):
    """The Uno image and its simavr harness, built (conftest's uno_built; skips without the tools)."""
    return uno_built


def _messages(core: UnoCore, seconds: float, gyro_mdps: int | None = 0, rx_at: dict | None = None):
    """Steps a lone core (no host) for `seconds`; returns (step outputs, decoded messages)."""
    decoder = FrameDecoder()
    outs, messages = [], []
    for k in range(int(seconds * 100) + 1):
        rx = (rx_at or {}).get(k, b"")
        out = core.step(k * 10, gyro_rate_mdps=gyro_mdps, rx=rx)
        outs.append(out)
        messages.extend((k * 10, f.message) for f in decoder.feed(out.tx))
    return outs, messages


# ---------------------------------------------------------------- no toolchain needed


def test_a_missing_libsimavr_is_named_in_the_error(monkeypatch, tmp_path):
    monkeypatch.setattr(harness, "missing_packages", lambda: {"libsimavr-dev": "/usr/include/simavr/sim_avr.h"})
    monkeypatch.setattr(harness, "LIBRARY", tmp_path / "libunocore.so")
    with pytest.raises(UnoSetupError, match=r"libsimavr-dev.*apt-get install libsimavr-dev"):
        harness.ensure_built(tmp_path / "firmware.elf")


def test_motor_pwm_is_read_from_the_compare_registers_or_the_port_bits():
    r = _Regs()
    r.ddrd, r.ddrb = 0b0110_1000, 0b0000_1000
    r.tccr0a, r.ocr0b = 0x20, 180  # pin 5 (left forward) on OC0B at 180
    r.tccr2a, r.ocr2a = 0x80, 90  # pin 11 (right forward) on OC2A at 90
    assert UnoCore._motors(r) == (180, 90)
    r.tccr0a, r.tccr2a = 0x80, 0x20  # now the backward inputs: OC0A (pin 6), OC2B (pin 3)
    r.ocr0a, r.ocr2b = 120, 200
    assert UnoCore._motors(r) == (-200, -120)
    r.tccr0a = r.tccr2a = 0  # analogWrite(255): timer off, port bit high
    r.portd = 1 << 5
    r.portb = 1 << 3
    assert UnoCore._motors(r) == (255, 255)


def test_the_servo_angle_is_the_inverse_of_servo_timer1s_mapping():
    board = uno.board_constants()
    core = UnoCore.__new__(UnoCore)  # only the conversion, no simulator
    core.board, core._servo_cdeg = board, 0
    span = board.servo_pulse_max_us - board.servo_pulse_min_us
    for angle in (-9000, -3000, -1234, 0, 450, 3000, 7000):
        servo = 9000 + board.servo_centre_trim_cdeg + board.servo_clockwise_sign * angle
        servo = max(0, min(18000, servo))
        pulse_us = board.servo_pulse_min_us + (servo * span + 9000) // 18000  # as the firmware
        r = _Regs()
        r.tccr1a, r.tccr1b, r.icr1, r.ocr1a = 0x82, 0x1A, 39999, pulse_us * 2  # mode 14, clk/8
        expected = board.servo_clockwise_sign * (servo - 9000 - board.servo_centre_trim_cdeg)
        assert abs(core._servo(r) - expected) <= 10, angle  # one microsecond is ~9.7 cdeg
    r.tccr1a = 0x02  # pulses off: the servo stays put
    assert core._servo(r) == core._servo_cdeg


# ---------------------------------------------------------------- the image in simavr


def test_the_uno_core_keeps_the_rover_core_protocol(built):
    from rovernav.cores import RoverCore

    core = UnoCore(reset_cause=1)
    assert isinstance(core, RoverCore)
    core.close()
    core.close()  # idempotent, as the protocol says


def test_the_gyro_model_answers_who_am_i_and_the_firmware_reports_no_gyro_fault(built):
    core = UnoCore(boot_id=42, reset_cause=1, sonar=lambda: 0)
    try:
        _, messages = _messages(core, 3.0, gyro_mdps=-1500)  # turning anticlockwise while it calibrates
        stats = core.stats()
    finally:
        core.close()
    assert stats["twi_whoami_reads"] >= 1
    assert stats["twi_gyro_reads"] >= 100 + 150  # the calibration's samples, then one a step
    assert stats["twi_nacked"] == 0
    hellos = [m for _, m in messages if isinstance(m, mg.Hello)]
    assert hellos and hellos[0].boot_id == 42 and hellos[0].schema_hash == mg.SCHEMA_HASH
    boot = [m for _, m in messages if isinstance(m, mg.Event) and m.kind == mg.EventKind.BOOT]
    assert boot and boot[0].arg == 1  # MCUSR's PORF, as the harness set it
    statuses = [m for _, m in messages if isinstance(m, mg.Status)]
    assert statuses and all(s.fault == mg.FaultCode.NONE for s in statuses)
    assert not any(s.flags & mg.StatusFlag.GYRO_FAULT for s in statuses)
    faults = [m for _, m in messages if isinstance(m, mg.Event) and m.kind == mg.EventKind.FAULT]
    assert faults == []


def test_a_gyro_that_stops_answering_is_a_gyro_fault(built):
    core = UnoCore(boot_id=1, reset_cause=1)
    try:
        _messages(core, 2.0)
        decoder = FrameDecoder()
        faults = []
        for k in range(201, 400):
            out = core.step(k * 10, gyro_rate_mdps=None)
            faults += [
                f.message.arg
                for f in decoder.feed(out.tx)
                if isinstance(f.message, mg.Event) and f.message.kind == mg.EventKind.FAULT
            ]
        assert core.stats()["twi_nacked"] > 0
    finally:
        core.close()
    assert mg.FaultCode.GYRO_SILENT in faults


def test_a_reset_keeps_the_eeprom_boot_counter_and_the_firmware_finds_the_cause_in_mcusr(built):
    core = UnoCore(boot_id=7, reset_cause=1)
    try:
        _, before = _messages(core, 2.0)
        core.reset(4)
        decoder = FrameDecoder()
        decoder.feed(b"\0")  # the frame the reset cut, if any, ends here
        after = []
        for k in range(201, 420):
            after += [f.message for f in decoder.feed(core.step(k * 10, gyro_rate_mdps=0).tx)]
        stats = core.stats()
    finally:
        core.close()
    hellos = [m.boot_id for _, m in before if isinstance(m, mg.Hello)] + [
        m.boot_id for m in after if isinstance(m, mg.Hello)
    ]
    boots = [m.arg for _, m in before if isinstance(m, mg.Event) and m.kind == mg.EventKind.BOOT] + [
        m.arg for m in after if isinstance(m, mg.Event) and m.kind == mg.EventKind.BOOT
    ]
    assert hellos == [7, 8] and boots == [1, 4]
    assert stats["resets"] == 1 and stats["twi_whoami_reads"] == 2


WATCHDOG_PROGRAM = r"""
#include <avr/io.h>
#include <avr/wdt.h>
int main(void) {
  uint8_t cause = MCUSR;
  MCUSR = 0;
  wdt_enable(WDTO_15MS);
  DDRB |= 1;
  PORTB |= 1;      /* a step that never ends */
  GPIOR0 = cause;
  for (;;) {}      /* no WDR: the watchdog resets the board */
}
"""


def test_a_watchdog_reset_is_seen_and_cuts_the_step_it_interrupts(built, tmp_path):
    src, elf = tmp_path / "wd.c", tmp_path / "wd.elf"
    src.write_text(WATCHDOG_PROGRAM)
    subprocess.run(["avr-gcc", "-mmcu=atmega328p", "-Os", "-o", str(elf), str(src)], check=True)
    core = UnoCore(elf=elf, reset_cause=1)
    try:
        for k in range(11):
            core.step(k * 10, gyro_rate_mdps=0)
        core._collect_steps(final=True)
        records, stats = core._records, core.stats()
    finally:
        core.close()
    assert stats["resets"] >= 5  # WDTO_15MS: ~16 ms each
    assert [r[4] for r in records] == list(range(len(records)))  # one step per boot
    assert [r[2] for r in records][:3] == [0x01, 0x08, 0x08]  # PORF, then WDRF
    periods_ms = [(b[0] - a[0]) / harness.CYCLES_PER_MS for a, b in zip(records, records[1:])]
    assert all(14 < p < 20 for p in periods_ms)
    assert all(r[1] > r[0] for r in records)  # each cut where the reset came


def test_idle_fast_forward_changes_nothing_the_firmware_or_the_host_can_see(built):
    """The same 3 s, with the harness skipping idle loop iterations and without: the same
    bytes on the UART, the same step edges to the cycle."""
    from rovernav.link.framing import encode_frame
    from rovernav.link.link import host_hello

    hello = encode_frame(host_hello(9), 0)
    runs = []
    for fast in (True, False):
        core = UnoCore(boot_id=5, reset_cause=1, fast_forward=fast)
        try:
            outs, _ = _messages(core, 3.0, gyro_mdps=250, rx_at={150: hello})
            core._collect_steps(final=True)
            runs.append((b"".join(o.tx for o in outs), list(core._records), core.stats()))
        finally:
            core.close()
    (tx_fast, steps_fast, st_fast), (tx_slow, steps_slow, st_slow) = runs
    assert st_fast["skipped_cycles"] > st_fast["cycle"] // 2 and st_slow["skipped_cycles"] == 0
    assert tx_fast == tx_slow and len(tx_fast) > 100
    assert steps_fast == steps_slow


@pytest.mark.mission
def test_rovernav_sim_rover_uno_reaches_the_target_and_reports_the_images_timing(built, tmp_path):
    out = tmp_path / "run"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "rovernav.cli",
            "sim",
            "seed-fig4-8-unknown-obstacle",
            "--rover",
            "uno",
            "--seed",
            "1",
            "--no-video",
            "--quiet",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "AVR simulated at" in result.stdout
    r = json.loads((out / "report.json").read_text())
    assert r["reached"] and r["collisions"] == 0 and r["obstacles_discovered"] == 1
    t = r["uno_timing"]
    assert t["sonar"]["pings"] > 0 and t["sonar"]["echoes"] == t["sonar"]["pings"]
    assert t["gyro"]["whoami_reads"] == 1 and t["gyro"]["nacked"] == 0
    stack = t["stack"]
    assert 0 < stack["used_bytes"] < 2048 - stack["static_bytes"] and stack["margin_bytes"] > 0
    assert t["speed"]["avr_x_real_time"] > 0  # the speed is a figure printed, not a timed test
    if not t["hooks"]["step_probe_pb0"]:
        pytest.skip("this image has no PB0 step probe: no step times to check")
    assert t["steps"] > 3000 and t["step_time"]["max_us"] <= 5000  # every step within half the 10 ms period
    for state in ("rotate", "drive", "scan"):
        figures = t["by_state"][state]
        assert figures["count"] > 0
        assert 0 < figures["median_us"] <= figures["p99_us"] <= figures["max_us"]
    assert t["by_flag"]["sonar"]["count"] > 0 and t["by_flag"]["fix"]["count"] > 0
    worst = t["worst_step"]
    assert worst["us"] == t["step_time"]["max_us"] and worst["state"] in t["by_state"]
    assert 0 < worst["t_s"] < r["mission_time_s"] and "x_m" in worst and "y_m" in worst
    jitter = t["period_jitter"]
    assert jitter["periods"] == t["steps"] - 1 and 0 <= jitter["p99_abs_us"] <= jitter["max_abs_us"]


@pytest.mark.mission
# A reset cuts a frame short; the image sends a frame delimiter at boot so that its HELLO is heard.
def test_a_firmware_reset_of_the_uno_mid_mission_is_brought_back_up_to_date(built):
    from rovernav.evaluation.report import build_report
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import Faults, SimOptions, Simulation

    sim = Simulation(
        load_scenario("seed-fig4-8-unknown-obstacle"),
        SimOptions(seed=1, rover="uno", max_time_s=90, faults=Faults(firmware_resets=[20.0])),
    )
    sim.run()
    r = build_report(sim, 1.0)
    assert sim.uno_timing()["resets"] == 1
    assert r["reached"] and r["collisions"] == 0


def test_rovernav_sim_help_documents_the_rover_flag():
    out = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    text = " ".join(out.stdout.split())
    assert "--rover {native,uno}" in text and "uno_timing" in text and "real time" in text


@pytest.mark.mission
def test_the_images_own_detour_planner_fits_the_step_period(built, tmp_path):
    # The step's limits, on the image through a detour of its own (the host does not replan):
    # no replanning step past half the 10 ms period, the period's jitter within 1 ms, and at
    # least 256 bytes of stack to spare. (The planner once took a 45 ms step here.)
    out = tmp_path / "run"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "rovernav.cli",
            "sim",
            "seed-fig4-8-unknown-obstacle",
            "--rover",
            "uno",
            "--no-host-replan",
            "--seed",
            "1",
            "--no-video",
            "--quiet",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    r = json.loads((out / "report.json").read_text())
    assert r["reached"] and r["collisions"] == 0
    t = r["uno_timing"]
    if not t["hooks"]["step_probe_pb0"]:
        pytest.skip("this image has no PB0 step probe: no step times to check")
    replanning = t["by_flag"]["replanning"]
    assert replanning["count"] >= 5  # the detour was planned over several steps
    assert replanning["max_us"] <= 5000
    assert t["by_state"]["planning"]["count"] >= 5  # in the rover's Planning mode, holding still
    assert t["step_time"]["max_us"] <= 5000  # and no other step of the mission past 5 ms either
    assert t["period_jitter"]["max_abs_us"] <= 1000
    assert t["stack"]["margin_bytes"] >= 256


@pytest.mark.mission
@pytest.mark.parametrize("scenario", ["full-echoes-posts", "full-echoes-wall"])
def test_the_images_detour_planner_with_its_obstacle_list_full_fits_the_step_period(built, scenario):
    # The detour planner's worst case: a sweep that echoes off more things than the rover keeps
    # obstacle disks (a row of 8 cm posts; a wall), then a detour of the rover's own (the host's
    # replanning off). Every planner slice, and every other step, within half the 10 ms period.
    from pathlib import Path

    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    root = Path(__file__).resolve().parents[1]
    header = (root / "firmware" / "lib" / "core" / "local_planner.h").read_text()
    max_echoes = int(re.search(r"kMaxEchoes = (\d+)", header).group(1))
    sim = Simulation(
        load_scenario(str(root / "scenarios" / f"{scenario}.toml")),
        SimOptions(seed=1, rover="uno", host_replan=False, max_time_s=300),
    )
    sim.run()
    t = sim.uno_timing()
    if not t["hooks"]["step_probe_pb0"]:
        pytest.skip("this image has no PB0 step probe: no step times to check")
    echoes = [m.arg for _, m in sim.mission.events if m.kind == mg.EventKind.SCAN_DONE]
    detours = [m.arg for _, m in sim.mission.events if m.kind == mg.EventKind.REPLANNED]
    assert max(echoes) > max_echoes  # one sweep filled the obstacle list
    assert detours and max(detours) >= 2  # and the rover planned its way round
    assert all(leg.reached for leg in sim.mission.legs) and sim.collisions == 0
    assert t["by_flag"]["replanning"]["count"] >= 5
    assert t["by_flag"]["replanning"]["max_us"] <= 5000
    assert t["step_time"]["max_us"] <= 5000
    assert t["period_jitter"]["max_abs_us"] <= 1000
    assert t["stack"]["margin_bytes"] >= 256
