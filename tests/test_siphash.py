"""SipHash-2-4 on the host: the paper's reference vectors, the values the firmware's test checks
(firmware/test/test_link/test_siphash.cpp), and the firmware's own build against random inputs."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovernav.link.siphash import siphash24

KEY = bytes(range(16))


def test_the_papers_reference_vectors():
    assert siphash24(KEY, b"") == 0x726FDB47DD0E0E31
    assert siphash24(KEY, bytes(range(15))) == 0xA129CA6149BE45E5


def test_the_values_the_firmwares_test_checks():
    got = {n: siphash24(KEY, bytes(range(n))) for n in (7, 8, 9, 16, 63)}
    assert got == {
        7: 0xAB0200F58B01D137,
        8: 0x93F5F5799A932462,
        9: 0x9E0082DF0BA9E4B0,
        16: 0x3F2ACC7F57C29BDB,
        63: 0x958A324CEB064572,
    }


def test_a_wrong_key_length_is_refused():
    with pytest.raises(ValueError, match="16 bytes"):
        siphash24(b"short", b"")


@pytest.fixture(scope="module")
def firmware_siphash(tmp_path_factory):
    """The firmware's siphash.cpp built for this machine as a tiny shared library."""
    root = Path(__file__).resolve().parents[1]
    out = tmp_path_factory.mktemp("sip") / "libsip.so"
    subprocess.run(
        [
            "g++",
            "-O2",
            "-shared",
            "-fPIC",
            "-std=c++14",
            f"-I{root / 'firmware/lib/link'}",
            str(root / "firmware/lib/link/siphash.cpp"),
            "-o",
            str(out),
        ],
        check=True,
    )
    lib = ctypes.CDLL(str(out))
    fn = lib._ZN8rovernav9siphash24EPKhS1_hPh  # rovernav::siphash24(key, data, uint8_t len, uint8_t* tag)
    fn.restype = None
    fn.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint8, ctypes.c_char_p]

    def siphash(key: bytes, data: bytes, n: int) -> int:
        tag = ctypes.create_string_buffer(8)
        fn(key, data, n, tag)
        return int.from_bytes(tag.raw, "little")

    return siphash


@settings(max_examples=200, deadline=None)
@given(key=st.binary(min_size=16, max_size=16), data=st.binary(max_size=255))
def test_the_firmware_and_the_host_agree_on_any_key_and_message(firmware_siphash, key, data):
    assert firmware_siphash(key, data, len(data)) == siphash24(key, data)


def test_the_benchmarks_hmac_sha256_is_hmac_sha256(tmp_path):
    # benchmarks/bench_mac.py compares SipHash with this implementation on the Uno: it must be right
    import hashlib
    import hmac
    import os

    root = Path(__file__).resolve().parents[1]
    lib_path = tmp_path / "libhmac.so"
    subprocess.run(
        ["g++", "-O2", "-shared", "-fPIC", str(root / "benchmarks/avr/hmac_sha256.cpp"), "-o", str(lib_path)],
        check=True,
    )
    fn = ctypes.CDLL(str(lib_path))._Z11hmac_sha256PKhS0_tPh
    for n in (0, 1, 15, 55, 56, 63, 64, 65, 200):
        key, data, out = os.urandom(16), os.urandom(n), ctypes.create_string_buffer(32)
        fn(key, data, n, out)
        assert out.raw == hmac.new(key, data, hashlib.sha256).digest(), n


AVR_PROGRAM = r"""
#include <avr/io.h>
#include "siphash.h"
uint8_t tags[65][8];
int main() {
  uint8_t key[16], msg[64];
  for (uint8_t i = 0; i < 16; ++i) key[i] = i;
  for (uint8_t i = 0; i < 64; ++i) msg[i] = i;
  for (uint8_t n = 0; n <= 64; ++n) rovernav::siphash24(key, msg, n, tags[n]);
  DDRB |= 1;
  for (;;) {
    PORTB |= 1;
    GPIOR0 = 0;
    PORTB &= (uint8_t)~1;
    for (volatile uint16_t d = 0; d < 4000; d++) {}
  }
}
"""


def test_siphash_on_the_avr_image(tmp_path):
    """The AVR's assembly round (sip_round_avr.S), built with the Uno's flags and run in simavr,
    gives the host's tags for every length 0..64 (every block boundary and tail)."""
    import shutil

    from rovernav.cores.uno import UnoCore
    from rovernav.cores.uno_harness import missing_packages

    if shutil.which("avr-g++") is None or missing_packages():
        pytest.skip("the AVR toolchain or simavr is not installed (scripts/test installs them)")
    root = Path(__file__).resolve().parents[1]
    src, elf = tmp_path / "main.cpp", tmp_path / "sip.elf"
    src.write_text(AVR_PROGRAM)
    subprocess.run(
        [
            "avr-g++",
            "-mmcu=atmega328p",
            "-Os",
            "-std=gnu++14",
            "-flto",
            "-mcall-prologues",
            f"-I{root / 'firmware/lib/link'}",
            str(src),
            str(root / "firmware/lib/link/siphash.cpp"),
            str(root / "firmware/lib/link/sip_round_avr.S"),
            "-o",
            str(elf),
        ],
        check=True,
    )
    symbols = subprocess.run(["avr-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    addr = next(int(line.split()[0], 16) for line in symbols.splitlines() if line.endswith(" tags")) & 0xFFFF
    core = UnoCore(elf=elf, reset_cause=1)
    try:
        for k in range(1, 40):
            core.step(k * 10, gyro_rate_mdps=0)
        got = [int.from_bytes(bytes(core.peek(addr + 8 * n + i) for i in range(8)), "little") for n in range(65)]
    finally:
        core.close()
    assert got == [siphash24(KEY, bytes(range(n))) for n in range(65)]
