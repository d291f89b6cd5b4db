"""`rovernav sim --rover uno --profile`: the Uno image's cycle profile in simavr, every cycle of a
step counted to its function and the interrupts apart, and the short function names it reports.

Builds the image (tools/build_uno.py) and the harness (make -C tools/avrsim unocore) when they
are missing (conftest.py's uno_built), and skips (saying which Debian package is missing) when the
AVR toolchain or libsimavr-dev is not installed. The whole-mission test is marked `mission`.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from rovernav.cores.elf import function_map, short_name
from rovernav.cores.uno import UnoCore


@pytest.fixture(scope="module")
def built(uno_built):
    """The Uno image and its simavr harness, built (conftest's uno_built; skips without the tools)."""
    return uno_built


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
