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
    assert got == {7: 0xAB0200F58B01D137, 8: 0x93F5F5799A932462, 9: 0x9E0082DF0BA9E4B0,
                   16: 0x3F2ACC7F57C29BDB, 63: 0x958A324CEB064572}


def test_a_wrong_key_length_is_refused():
    with pytest.raises(ValueError, match="16 bytes"):
        siphash24(b"short", b"")


@pytest.fixture(scope="module")
def firmware_siphash(tmp_path_factory):
    """The firmware's siphash.cpp built for this machine as a tiny shared library."""
    root = Path(__file__).resolve().parents[1]
    out = tmp_path_factory.mktemp("sip") / "libsip.so"
    subprocess.run(["g++", "-O2", "-shared", "-fPIC", "-std=c++14", f"-I{root / 'firmware/lib/link'}",
                    str(root / "firmware/lib/link/siphash.cpp"), "-o", str(out)], check=True)
    lib = ctypes.CDLL(str(out))
    fn = lib._ZN8rovernav9siphash24EPKhS1_t   # rovernav::siphash24(const uint8_t*, const uint8_t*, uint16_t)
    fn.restype = ctypes.c_uint64
    fn.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint16]
    return fn


@settings(max_examples=200, deadline=None)
@given(key=st.binary(min_size=16, max_size=16), data=st.binary(max_size=80))
def test_the_firmware_and_the_host_agree_on_any_key_and_message(firmware_siphash, key, data):
    assert firmware_siphash(key, data, len(data)) == siphash24(key, data)


def test_the_benchmarks_hmac_sha256_is_hmac_sha256(tmp_path):
    # benchmarks/bench_mac.py compares SipHash with this implementation on the Uno: it must be right
    import hashlib
    import hmac
    import os

    root = Path(__file__).resolve().parents[1]
    lib_path = tmp_path / "libhmac.so"
    subprocess.run(["g++", "-O2", "-shared", "-fPIC", str(root / "benchmarks/avr/hmac_sha256.cpp"), "-o",
                    str(lib_path)], check=True)
    fn = ctypes.CDLL(str(lib_path))._Z11hmac_sha256PKhS0_tPh
    for n in (0, 1, 15, 55, 56, 63, 64, 65, 200):
        key, data, out = os.urandom(16), os.urandom(n), ctypes.create_string_buffer(32)
        fn(key, data, n, out)
        assert out.raw == hmac.new(key, data, hashlib.sha256).digest(), n
