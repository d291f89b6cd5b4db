"""`rovernav sim --rover uno`: the Uno image in simavr, with the simulated world on its pins.

Builds the image (tools/build_uno.py) and the harness (make -C tools/avrsim unocore) when they
are missing, and skips (saying which Debian package is missing) when the AVR toolchain or
libsimavr-dev is not installed. The whole-mission tests are marked `mission`.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from rovernav.cores import uno
from rovernav.cores import uno_harness as harness
from rovernav.cores.elf import function_map, short_name
from rovernav.cores.uno import UnoCore
from rovernav.cores.uno_harness import UnoSetupError, _Regs
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder


def _skip_reason() -> str | None:
    missing = harness.missing_packages()
    if missing:
        return "the Uno simulation needs Debian packages: " + ", ".join(sorted(missing))
    return None


@pytest.fixture(scope="module")
def built():
    reason = _skip_reason()
    if reason:
        pytest.skip(reason)
    try:
        return harness.ensure_built()
    except UnoSetupError as exc:
        if "apt-get install" in str(exc) or "toolchain" in str(exc):
            pytest.skip(str(exc))
        raise


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
    from rovernav.scenario import load_scenario
    from rovernav.sim.report import build_report
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


# ---------------------------------------------------------------- the cycle profile (--profile)

PROFILE_PROGRAM = r"""
#include <avr/io.h>
#include <avr/interrupt.h>
volatile uint16_t ticks;
ISR(TIMER0_OVF_vect) { ticks++; }
__attribute__((noinline)) uint16_t work(uint16_t n) {
  volatile uint16_t s = 0;
  for (uint16_t i = 0; i < n; i++) s += i;
  return s;
}
__attribute__((noinline)) float fwork(float x) { return x * 1.5f + x / 3.0f; }
volatile float f = 2.0f;
int main(void) {
  TCCR0B = 1;            /* Timer0 at clk/1: an overflow every 256 cycles */
  TIMSK0 = 1;
  sei();
  DDRB |= 1;
  for (uint8_t k = 0;; k++) {
    PORTB |= 1;          /* a step: work(), and every other step fwork() too */
    work(300);
    if (k & 1) f = fwork(f);
    GPIOR0 = (k & 1) ? 0x10 : 0x20;
    PORTB &= ~1;
    for (volatile uint16_t d = 0; d < 3000; d++) {}
  }
}
"""


def test_the_profile_counts_every_cycle_of_a_step_to_its_function_and_interrupts_apart(built, tmp_path):
    src, elf = tmp_path / "prof.c", tmp_path / "prof.elf"
    src.write_text(PROFILE_PROGRAM)
    subprocess.run(["avr-gcc", "-mmcu=atmega328p", "-Os", "-o", str(elf), str(src)], check=True)
    fmap = function_map(elf)
    assert "work" in fmap.names and "main" in fmap.names and "__vector_16" in fmap.names
    assert fmap.vector_handlers[16] == "__vector_16" and fmap.vector_handlers[1] == "__bad_interrupt"
    core = UnoCore(elf=elf, reset_cause=1, profile=True)
    try:
        for k in range(31):
            core.step(k * 10, gyro_rate_mdps=0)
        t = core.timing()
    finally:
        core.close()
    prof, steps = t["profile"], t["steps"]
    assert steps > 20 and prof["open_frames_at_step_end"] == 0
    all_, fix, sonar = (prof["kinds"][k] for k in ("all", "fix", "sonar"))
    assert all_["steps"] == steps and fix["steps"] + sonar["steps"] == steps
    assert all_["counted_share"] == 1.0 and all_["named_share"] == 1.0  # every cycle, all in named code
    work = next(r for r in all_["functions"] if r["function"] == "work")
    assert work["calls_per_step"] == 1.0 and work["share"] > 0.5
    # work() calls nothing: its inclusive time is its own, the interrupts taken inside it left out
    assert work["inclusive_us_per_step"] == work["us_per_step"]
    timer0 = [i for i in all_["interrupts"] if i["vector"] == 16]
    assert timer0 and timer0[0]["handler"] == "__vector_16" and timer0[0]["source"] == "TIMER0_OVF"
    mean_cycles = all_["mean_step_us"] * 16
    assert timer0[0]["entries_per_step"] == pytest.approx(mean_cycles / 256, rel=0.1)
    shares = sum(r["share"] for r in all_["functions"]) + sum(i["share"] for i in all_["interrupts"])
    assert shares == pytest.approx(1.0, abs=0.01)
    # the float routines run in the FIX-flagged steps only, called from fwork()
    assert sonar["float_library"]["cycles"] == 0
    fl = fix["float_library"]
    assert fl["cycles"] > 0 and [c["caller"] for c in fl["callers"]] == ["fwork"]
    assert {"main"} == {e["caller"] for e in fix["calls"] if e["callee"] in ("work", "fwork")}
    assert fix["mean_step_us"] > sonar["mean_step_us"]
    worst = prof["kinds"]["worst_1pct"]
    assert worst["steps"] == 1 and worst["flags"]["fix"] == 1  # the longest step is a float one
    json.dumps(prof, allow_nan=False)


@pytest.mark.mission
def test_a_profiled_mission_names_the_estimators_update_in_the_fix_steps(built):
    from rovernav.scenario import load_scenario
    from rovernav.sim.runner import SimOptions, Simulation

    sim = Simulation(load_scenario("seed-fig4-8-unknown-obstacle"), SimOptions(seed=1, rover="uno", max_time_s=8))
    sim.core.enable_profile()
    sim.run()
    t = sim.uno_timing()
    if not t["hooks"]["descriptor_gpior0"]:
        pytest.skip("this image has no PB0 probe or GPIOR0 descriptor: no steps to profile")
    kinds = t["profile"]["kinds"]
    all_, fix = kinds["all"], kinds["fix"]
    assert all_["steps"] == t["steps"] and fix["steps"] == t["by_flag"]["fix"]["count"] > 0
    assert all_["counted_share"] == pytest.approx(1.0, abs=0.001)
    assert all_["named_share"] >= 0.90 and fix["named_share"] >= 0.90
    # Estimator::update is inlined by LTO; what remains of it out of line is sequential_update
    estimator = re.compile(r"Estimator::update|sequential_update")
    fix_names = [r["symbol"] for r in fix["functions"] + fix["inclusive"]]
    assert any(estimator.search(n) for n in fix_names), fix_names
    quiet = kinds["no_flags"]
    if quiet["steps"]:
        assert not any(estimator.search(r["symbol"]) for r in quiet["functions"] + quiet["inclusive"])
    assert t["profile"]["open_frames_at_step_end"] == 0


def test_rovernav_sim_help_documents_the_profile_flag_and_it_needs_the_uno():
    out = subprocess.run([sys.executable, "-m", "rovernav.cli", "sim", "--help"], capture_output=True, text=True)
    text = " ".join(out.stdout.split())
    assert "--profile" in text and 'uno_timing["profile"]' in text and "FIX" in text
    out = subprocess.run(
        [sys.executable, "-m", "rovernav.cli", "sim", "--profile", "--max-time", "1"], capture_output=True, text=True
    )
    assert out.returncode == 2 and "--rover uno" in out.stderr


def test_short_names_drop_parameters_clones_and_the_namespace():
    assert (
        short_name(
            "rovernav::core::Rover::step(rovernav::core::Inputs const&, rovernav::core::Outputs&) [clone .constprop.3]"
        )
        == "core::Rover::step"
    )
    assert (
        short_name(
            "rovernav::core::(anonymous namespace)::sequential_update(float const*, float*) [clone .lto_priv.164]"
        )
        == "core::sequential_update"
    )
    assert (
        short_name("rovernav::core::Estimator::position_sd_mm() const [clone .constprop.102]")
        == "core::Estimator::position_sd_mm"
    )
    assert short_name("__subsf3 / __addsf3") == "__subsf3 / __addsf3"


# ---------------------------------------------------------------- signed frames on the image


def test_the_image_takes_a_key_over_usb_stores_it_in_eeprom_and_signs_with_it_after_a_reset(built):
    from tests.core_transport import CoreTransport

    from rovernav.link.framing import FrameDecoder, Signer, Verifier, encode_frame
    from rovernav.link.provision import provision

    key = bytes(range(200, 216))
    core = uno.UnoCore(boot_id=3, reset_cause=2)  # the USB port opened: an external reset
    try:
        port = CoreTransport(core)
        assert provision(port, key, clock=port.clock).startswith("stored the key")  # no key yet: first use
        port.run_ms(1000)  # the EEPROM record goes a byte a step, never waiting for the EEPROM
        board = uno.board_constants()
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(key)
        # After a reset the image loads the key: its HELLO says it signs, signed with the key, and
        # it obeys only what the key signs.
        core.reset(2)
        port.from_rover = b""
        port.run_ms(2500)  # the image boots in about 1.6 s (the gyro's calibration)
        heard = FrameDecoder(Verifier(key, mg.SIGN_ROVER_TO_HOST))
        hello = next(f for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Hello))
        assert hello.counter is not None and hello.message.signing == 1
        host = Signer(key, mg.SIGN_HOST_TO_ROVER)
        host.jump_past((hello.message.min_counter_hi << 32 | hello.message.min_counter_lo) - 1)
        port.from_rover = b""
        port.write(encode_frame(mg.Stop(reason=0), 9))  # unsigned: refused
        port.write(encode_frame(mg.Stop(reason=0), 10, host))  # signed: obeyed
        port.run_ms(300)
        acks = [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)]
        assert acks == [10] and heard.counters.dropped == 0
    finally:
        core.close()


@pytest.mark.parametrize(
    "slots, expected_rx",
    [
        ([(1000, 5000, 5, True), (9999, 99999, 6, False)], 5000),  # the newer slot torn (bad CRC): the other
        ([(1000, 5000, 5, True), (2000, 9000, 6, True)], 9000),  # both whole: the newer age
        ([(2000, 9000, 255, True), (3000, 12000, 0, True)], 12000),  # ages wrap: 0 follows 255
        ([(1, 2, 3, False), (4, 5, 6, False)], 0),  # none whole: from zero
    ],
)
def test_the_image_resumes_from_the_newest_whole_counter_slot(built, slots, expected_rx):
    from rovernav.link.framing import FrameDecoder, Verifier, crc16

    key = bytes(range(100, 116))
    core = uno.UnoCore(boot_id=3, reset_cause=1)
    try:
        base = uno.board_constants().eeprom_link_addr
        core.eeprom(base, uno.link_key_record(key))
        for i, (tx, rx, age, whole) in enumerate(slots):
            rec = tx.to_bytes(6, "little") + rx.to_bytes(6, "little") + bytes((age,))
            crc = crc16(rec) ^ (0 if whole else 0x5A5A)
            core.eeprom(base + 19 + 15 * i, rec + crc.to_bytes(2, "little"))
        heard = FrameDecoder(Verifier(key, mg.SIGN_ROVER_TO_HOST))
        frames = []
        for k in range(1, 260):
            frames += heard.feed(core.step(k * 10, gyro_rate_mdps=0).tx)
        hello = next(f for f in frames if isinstance(f.message, mg.Hello))
        assert (
            hello.message.min_counter_hi << 32 | hello.message.min_counter_lo
        ) == expected_rx + mg.SIGN_RESET_MARGIN + 1
        # ... and it stored the resumed counters at once, in the slot it did not take
        stored = [core.eeprom(base + 19 + 15 * i, size=15) for i in range(2)]
        whole = [s for s in stored if crc16(s[:13]) == int.from_bytes(s[13:], "little")]
        assert any(int.from_bytes(s[6:12], "little") == expected_rx + mg.SIGN_RESET_MARGIN for s in whole)
    finally:
        core.close()


# ---------------------------------------------------------------- the owner's consent on the image

OWNER_KEY = bytes(range(120, 136))
STRANGER_KEY = bytes(range(7, 23))


def _boot_events(frames) -> list[int]:
    return [f.message.arg for f in frames if isinstance(f.message, mg.Event) and f.message.kind == mg.EventKind.BOOT]


def _recording_port(core):
    """A CoreTransport that also keeps every byte the host read (`heard`)."""
    from tests.core_transport import CoreTransport

    class Recording(CoreTransport):
        heard = b""

        def _read(self, max_bytes, timeout_s):
            data = super()._read(max_bytes, timeout_s)
            self.heard += data
            return data

    return Recording(core)


def test_a_keyed_image_refuses_a_strangers_provision_after_power_on_brown_out_and_watchdog_resets_and_takes_it_with_the_pin_held(
    built,
):
    from rovernav.link.framing import Verifier
    from rovernav.link.provision import NeedsConsent, provision

    core = uno.UnoCore(boot_id=5, reset_cause=0x01, key=OWNER_KEY)  # power-on, the owner's key in EEPROM
    board = uno.board_constants()
    try:
        port = _recording_port(core)
        for cause in (None, 0x04, 0x08):  # power-on (the first boot), brown-out, watchdog
            if cause is not None:
                core.reset(cause)  # MCUSR as each reset leaves it
                port.from_rover = b""
            with pytest.raises(NeedsConsent) as info:
                provision(port, STRANGER_KEY, clock=port.clock)
            assert info.value.pin == board.pin_consent == mg.SIGN_CONSENT_PIN
            port.run_ms(500)
            assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(OWNER_KEY)
        # A jumper from D7 to GND, then a reset (the USB port opened): the image reads the pin as it
        # starts, says so in its boot EVENT, and takes an unsigned key.
        core.hold_consent_pin(True)
        core.reset(0x02)
        port.from_rover = port.heard = b""
        line = provision(port, STRANGER_KEY, clock=port.clock)
        assert "consent pin (D7)" in line
        booted = FrameDecoder(Verifier(OWNER_KEY, mg.SIGN_ROVER_TO_HOST, require=False)).feed(port.heard)
        port.run_ms(1000)  # the EEPROM record goes a byte a step
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(STRANGER_KEY)
        # The jumper off again: after the next reset the pin reads high, and the new key holds.
        core.hold_consent_pin(False)
        core.reset(0x01)
        port.from_rover = port.heard = b""
        with pytest.raises(NeedsConsent):
            provision(port, OWNER_KEY, clock=port.clock)
        port.run_ms(200)
        after = FrameDecoder(Verifier(STRANGER_KEY, mg.SIGN_ROVER_TO_HOST, require=False)).feed(
            port.heard + port.from_rover
        )
    finally:
        core.close()
    assert mg.SIGN_CONSENT_RESET_BIT | 0x02 in _boot_events(booted)
    assert _boot_events(after) == [0x01]


def test_a_keyed_image_takes_a_new_key_signed_with_its_current_one_and_signs_with_it_after_a_reset(built):
    from tests.core_transport import CoreTransport

    from rovernav.link.framing import Signer, Verifier, encode_frame
    from rovernav.link.provision import provision

    core = uno.UnoCore(boot_id=5, reset_cause=0x01, key=OWNER_KEY)
    board = uno.board_constants()
    try:
        port = CoreTransport(core)
        line = provision(port, STRANGER_KEY, clock=port.clock, current_key=OWNER_KEY)
        assert "current key's signature" in line
        port.run_ms(1000)
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(STRANGER_KEY)
        core.reset(0x01)
        port.from_rover = b""
        port.run_ms(2500)
        heard = FrameDecoder(Verifier(STRANGER_KEY, mg.SIGN_ROVER_TO_HOST))
        hello = next(f for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Hello))
        host = Signer(STRANGER_KEY, mg.SIGN_HOST_TO_ROVER)
        host.jump_past((hello.message.min_counter_hi << 32 | hello.message.min_counter_lo) - 1)
        port.from_rover = b""
        port.write(encode_frame(mg.Stop(reason=0), 21, Signer(OWNER_KEY, mg.SIGN_HOST_TO_ROVER)))  # the old key
        port.write(encode_frame(mg.Stop(reason=0), 22, host))  # the new one
        port.run_ms(300)
        acks = [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)]
    finally:
        core.close()
    assert acks == [22]
