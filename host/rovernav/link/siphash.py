"""SipHash-2-4 (Aumasson and Bernstein, 2012): a keyed 64-bit MAC with a 128-bit key, made for
short messages; the host's twin of firmware/lib/link/siphash.cpp (both are checked against the
paper's reference vectors, and against each other)."""

from __future__ import annotations

KEY_BYTES = 16
_MASK = (1 << 64) - 1


def _rotl(x: int, b: int) -> int:
    return ((x << b) | (x >> (64 - b))) & _MASK


def siphash24(key: bytes, data: bytes) -> int:
    """SipHash-2-4 of `data` under the 16-byte `key`, as a 64-bit integer (its little-endian bytes
    are the reference implementation's output)."""
    if len(key) != KEY_BYTES:
        raise ValueError(f"a SipHash key is {KEY_BYTES} bytes, got {len(key)}")
    k0, k1 = int.from_bytes(key[:8], "little"), int.from_bytes(key[8:], "little")
    v = [k0 ^ 0x736F6D6570736575, k1 ^ 0x646F72616E646F6D, k0 ^ 0x6C7967656E657261, k1 ^ 0x7465646279746573]

    def sip_round() -> None:
        v[0] = (v[0] + v[1]) & _MASK
        v[1] = _rotl(v[1], 13) ^ v[0]
        v[0] = _rotl(v[0], 32)
        v[2] = (v[2] + v[3]) & _MASK
        v[3] = _rotl(v[3], 16) ^ v[2]
        v[0] = (v[0] + v[3]) & _MASK
        v[3] = _rotl(v[3], 21) ^ v[0]
        v[2] = (v[2] + v[1]) & _MASK
        v[1] = _rotl(v[1], 17) ^ v[2]
        v[2] = _rotl(v[2], 32)

    def absorb(m: int) -> None:
        v[3] ^= m
        sip_round()
        sip_round()
        v[0] ^= m

    whole = len(data) - len(data) % 8
    for i in range(0, whole, 8):
        absorb(int.from_bytes(data[i : i + 8], "little"))
    absorb(((len(data) & 0xFF) << 56) | int.from_bytes(data[whole:], "little"))
    v[2] ^= 0xFF
    for _ in range(4):
        sip_round()
    return v[0] ^ v[1] ^ v[2] ^ v[3]
