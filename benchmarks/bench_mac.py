"""The frame tag's cost on the Uno: SipHash-2-4 against HMAC-SHA256, measured on AVR images.

    python benchmarks/bench_mac.py

For each MAC and message length it builds a small ATmega328P program with the project's AVR flags
(platformio.ini's [env:uno], as tools/build_uno.py reads them) that computes the tag of the
message again and again with D8 (PB0) high, runs it in simavr through the simulator's harness
(rovernav.cores.uno.UnoCore), and prints the microseconds per tag at 16 MHz (the median of the
steps: cycle counts, not wall time) and the flash the MAC adds over the same program without
it (avr-size). The MACs: firmware/lib/link/siphash.cpp, and benchmarks/avr/hmac_sha256.cpp
(checked against Python's hmac by tests/test_siphash.py).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LENGTHS = (8, 16, 32, 48, 64)

PROGRAM = r"""
#include <avr/io.h>
#include <stdint.h>
#include "siphash.h"
void hmac_sha256(const uint8_t* key, const uint8_t* data, uint16_t len, uint8_t* out);
volatile uint8_t sink;
uint8_t key[16], msg[64], out[32];
int main() {
  for (uint8_t i = 0; i < 64; ++i) msg[i] = i;
  for (uint8_t i = 0; i < 16; ++i) key[i] = (uint8_t)(i * 7);
  DDRB |= 1;
  for (;;) {
    PORTB |= 1;
#if MAC == 1
    uint8_t t[8];
    rovernav::siphash24(key, msg, LEN, t);
    sink = t[0];
#elif MAC == 2
    hmac_sha256(key, msg, LEN, out);
    sink = out[0];
#else
    sink = msg[LEN - 1];
#endif
    GPIOR0 = 0;
    PORTB &= (uint8_t)~1;
    for (volatile uint16_t d = 0; d < 4000; d++) {}
    msg[0]++;
  }
}
"""


def avr_flags() -> list[str]:
    out = subprocess.run(
        [sys.executable, str(ROOT / "tools/build_uno.py"), "--print-flags", "uno"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return [f for f in out if f.startswith(("-m", "-f")) and f != "-mmcu"]


def build(mac: int, length: int, work: Path) -> tuple[Path, int]:
    src = work / "main.cpp"
    src.write_text(PROGRAM)
    elf = work / f"mac{mac}-{length}.elf"
    cmd = [
        "avr-g++",
        "-mmcu=atmega328p",
        "-Os",
        "-std=gnu++14",
        "-flto",
        *avr_flags(),
        f"-DMAC={mac}",
        f"-DLEN={length}",
        f"-I{ROOT / 'firmware/lib/link'}",
        str(src),
        str(ROOT / "firmware/lib/link/siphash.cpp"),
        str(ROOT / "firmware/lib/link/sip_round_avr.S"),
        str(ROOT / "benchmarks/avr/hmac_sha256.cpp"),
        "-Wl,--gc-sections",
        "-ffunction-sections",
        "-o",
        str(elf),
    ]
    subprocess.run(cmd, check=True)
    text = (
        subprocess.run(["avr-size", "--format=berkeley", str(elf)], capture_output=True, text=True, check=True)
        .stdout.splitlines()[1]
        .split()
    )
    return elf, int(text[0]) + int(text[1])  # text + data: the flash


def tag_us(elf: Path) -> float:
    from rovernav.cores.uno import UnoCore

    core = UnoCore(elf=elf, reset_cause=1)
    try:
        for k in range(1, 60):
            core.step(k * 10, gyro_rate_mdps=0)
        t = core.timing()
    finally:
        core.close()
    return t["step_time"]["median_us"]


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args(argv)
    sys.path.insert(0, str(ROOT / "host"))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        rows = []
        for length in LENGTHS:
            base_elf, base_flash = build(0, length, work)
            base_us = tag_us(base_elf)
            row = [length]
            for mac in (1, 2):
                elf, flash = build(mac, length, work)
                row += [tag_us(elf) - base_us, flash - base_flash]
            rows.append(row)
    print("| message bytes | SipHash-2-4 (us) | HMAC-SHA256 (us) | SipHash / HMAC |")
    print("|---|---|---|---|")
    for length, sip_us, _, hmac_us, _ in rows:
        print(f"| {length} | {sip_us:.0f} | {hmac_us:.0f} | {sip_us / hmac_us:.2f} |")
    print(
        f"\nflash added (bytes): SipHash-2-4 {statistics.median(r[2] for r in rows):.0f}, "
        f"HMAC-SHA256 {statistics.median(r[4] for r in rows):.0f} (medians over the lengths); "
        "16 MHz, cycles counted in simavr"
    )
    print()
    frame_table(work_dir=None)
    return 0


def frame_table(work_dir) -> None:
    """The tag of every message's signed frame: the bytes it covers (the direction byte, the
    header, the payload, the counter) and its cost on the Uno."""
    from rovernav.link import messages_gen as mg

    covered = {cls.NAME: 1 + 3 + cls.STRUCT.size + mg.SIGN_COUNTER_BYTES for cls in mg.MESSAGES.values()}
    cost_us: dict[int, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for length in sorted(set(covered.values())):
            base_elf, _ = build(0, length, work)
            elf, _ = build(1, length, work)
            cost_us[length] = tag_us(elf) - tag_us(base_elf)
    print("| message | payload | signed frame on the wire | bytes the tag covers | tag on the Uno (us) | cycles |")
    print("|---|---|---|---|---|---|")
    for cls in sorted(mg.MESSAGES.values(), key=lambda c: c.ID):
        n = covered[cls.NAME]
        wire = 3 + cls.STRUCT.size + mg.SIGN_COUNTER_BYTES + mg.SIGN_TAG_BYTES + 2 + 2
        print(f"| {cls.NAME} | {cls.STRUCT.size} | {wire} | {n} | {cost_us[n]:.0f} | {cost_us[n] * 16:.0f} |")


if __name__ == "__main__":
    sys.exit(main())
