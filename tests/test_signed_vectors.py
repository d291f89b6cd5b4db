"""The signed-frame golden vectors (protocol/vectors.json `signed_frames`): computed by the
reference encoder in protocol/generate.py (its own SipHash-2-4, from the paper), checked here
against the host's Signer and Verifier (host/rovernav/link/framing.py) in both directions. The
C++ side checks the same vectors with the rover's FrameAuth (firmware/test/test_link)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder, Signer, Verifier, cobs_decode, encode_frame
from rovernav.link.siphash import siphash24

ROOT = Path(__file__).resolve().parent.parent
VECTORS = json.loads((ROOT / "protocol" / "vectors.json").read_text())
SIGNED = VECTORS["signed_frames"]
DIRECTIONS = {"host_to_rover": mg.SIGN_HOST_TO_ROVER, "rover_to_host": mg.SIGN_ROVER_TO_HOST}


def _generator():
    spec = importlib.util.spec_from_file_location(
        "rovernav_protocol_generate_signed", ROOT / "protocol" / "generate.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


generate = _generator()


def _message(v: dict):
    cls = mg.MESSAGES_BY_NAME[v["message"]]
    return cls(**{k: tuple(x) if isinstance(x, list) else x for k, x in v["fields"].items()})


def test_the_reference_siphash_gives_the_papers_vector_and_agrees_with_the_hosts():
    key, m, expected = generate.SIPHASH_PAPER_VECTOR
    assert generate.reference_siphash24(key, m) == bytes.fromhex("e545be4961ca29a1")
    assert expected == 0xA129CA6149BE45E5
    # at every length across the block boundaries, as the frames' lengths fall
    for n in range(0, 70):
        k = bytes((7 * n + i) & 0xFF for i in range(16))
        data = bytes((31 * i + n) & 0xFF for i in range(n))
        assert int.from_bytes(generate.reference_siphash24(k, data), "little") == siphash24(k, data), n


def test_the_reference_siphash_refuses_a_changed_round():
    # check_reference_siphash is what stops a broken reference from writing vectors
    saved = generate._sip_round
    try:
        generate._sip_round = lambda v0, v1, v2, v3: saved(v1, v0, v2, v3)
        with pytest.raises(AssertionError, match="paper's vector"):
            generate.check_reference_siphash()
    finally:
        generate._sip_round = saved
    generate.check_reference_siphash()


def test_the_vectors_cover_both_directions_hello_and_max_payload_and_counters_above_2_32():
    assert {v["direction"] for v in SIGNED} == set(DIRECTIONS)
    sizes = {v["name"]: len(cobs_decode(bytes.fromhex(v["frame_hex"])[:-1])) for v in SIGNED}
    assert any(v["message"] == "hello" and v["direction"] == d for v in SIGNED for d in DIRECTIONS)
    assert max(sizes.values()) == mg.MAX_SIGNED_RAW_FRAME  # a max_payload frame, signed
    assert any(len(bytes.fromhex(v["frame_hex"])) == mg.UART_BUFFER_BYTES for v in SIGNED)
    assert any(v["counter"] > 2**32 for v in SIGNED if v["direction"] == "host_to_rover")
    assert any(v["counter"] > 2**32 for v in SIGNED if v["direction"] == "rover_to_host")


@pytest.mark.parametrize("v", SIGNED, ids=[v["name"] for v in SIGNED])
def test_the_hosts_signer_makes_each_signed_vector_byte_for_byte(v):
    key, direction = bytes.fromhex(v["key_hex"]), DIRECTIONS[v["direction"]]
    signer = Signer(key, direction, clock=lambda: float(mg.SIGN_EPOCH_UNIX_S))  # its clock at 0 ms
    signer.jump_past(v["counter"] - 1)
    assert encode_frame(_message(v), v["seq"], signer).hex() == v["frame_hex"]
    assert signer.last_counter == v["counter"]
    # the tag, and what it is SipHash-2-4 of
    mac_input = bytes.fromhex(v["mac_input_hex"])
    assert mac_input[0] == direction
    assert siphash24(key, mac_input).to_bytes(8, "little")[: mg.SIGN_TAG_BYTES].hex() == v["tag_hex"]
    raw = cobs_decode(bytes.fromhex(v["frame_hex"])[:-1])
    assert raw[: len(mac_input) - 1] == mac_input[1:]
    assert raw[len(mac_input) - 1 : -2].hex() == v["tag_hex"]
    assert (
        int.from_bytes(raw[len(mac_input) - 1 - mg.SIGN_COUNTER_BYTES : len(mac_input) - 1], "little") == v["counter"]
    )


@pytest.mark.parametrize("v", SIGNED, ids=[v["name"] for v in SIGNED])
def test_the_hosts_verifier_takes_each_signed_vector_once_and_refuses_it_with_another_key_or_direction(v):
    key, direction = bytes.fromhex(v["key_hex"]), DIRECTIONS[v["direction"]]
    wire = bytes.fromhex(v["frame_hex"])
    dec = FrameDecoder(Verifier(key, direction))
    frames = dec.feed(wire)
    assert len(frames) == 1 and frames[0].counter == v["counter"] and frames[0].message == _message(v)
    assert dec.feed(wire) == [] and dec.counters.replayed == 1  # the same counter again
    other_key = bytes(b ^ 1 for b in key)
    other_direction = DIRECTIONS["rover_to_host" if v["direction"] == "host_to_rover" else "host_to_rover"]
    for verifier in (Verifier(other_key, direction), Verifier(key, other_direction)):
        dec = FrameDecoder(verifier)
        assert dec.feed(wire) == [] and dec.counters.bad_tag == 1


def test_the_vectors_are_what_the_reference_encoder_computes_now():
    d = generate.load()
    recomputed = generate.update_vectors(d, json.loads(json.dumps(VECTORS)))
    assert recomputed["signed_frames"] == SIGNED


def test_the_drift_check_fails_when_a_signed_vectors_tag_is_stale(tmp_path):
    import shutil
    import subprocess
    import sys

    for rel in ("protocol", "firmware/lib/link", "firmware/test/test_link", "host/rovernav/link"):
        shutil.copytree(ROOT / rel, tmp_path / rel)
    target = tmp_path / "protocol" / "vectors.json"
    vectors = json.loads(target.read_text())
    vectors["signed_frames"][0]["counter"] += 1  # authored field changed, computed ones left
    target.write_text(json.dumps(vectors, indent=1) + "\n")
    result = subprocess.run(
        [sys.executable, str(tmp_path / "protocol" / "generate.py"), "--check"], capture_output=True, text=True
    )
    assert result.returncode == 1
    assert "protocol/vectors.json" in result.stderr and "--update-vectors" in result.stderr
