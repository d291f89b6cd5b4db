"""`rovernav provision` against the rover's firmware core (its C ABI), in simulated time: the key
is sent only after the rover is seen to boot, a rover with no key takes it only soon after a
reset, and a rover with a key changes it only with its owner's consent (the PROVISION signed with
its current key, or the consent pin held to GND at its reset)."""

from __future__ import annotations

import time

import pytest
from tests.core_transport import CoreTransport

from rovernav.cores import NativeCore
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder, Signer, Verifier, cobs_decode, encode_frame
from rovernav.link.provision import NeedsConsent, ProvisionError, WrongCurrentKey, provision

KEY = bytes(range(50, 66))
NEW_KEY = bytes(range(90, 106))
# MCUSR's reset flags: power-on, external (button, DTR), brown-out, watchdog; none (behind optiboot)
RESET_CAUSES = (0x01, 0x02, 0x04, 0x08, 0x00)


def test_a_rover_that_has_just_booted_takes_the_key_and_answers_signed_with_it():
    port = CoreTransport(NativeCore())  # opening the USB port reset it: it boots now
    line = provision(port, KEY, clock=port.clock)
    assert line.startswith("stored the key")
    assert port.core.take_key_change() == ("store", KEY)
    # From now on it takes only what this key signs, and signs what it says.
    port.from_rover = b""
    heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST))
    port.write(encode_frame(mg.Stop(reason=0), 1))  # unsigned
    port.write(encode_frame(mg.Stop(reason=0), 2, Signer(KEY, mg.SIGN_HOST_TO_ROVER)))  # signed
    port.run_ms(100)
    said = [f.message for f in heard.feed(port.from_rover)]
    assert [m.seq for m in said if isinstance(m, mg.Ack)] == [2]
    assert port.core.auth_counters()["not_signed"] == 1 and heard.counters.dropped == 0


def test_over_a_port_that_did_not_reset_the_rover_nothing_is_sent():
    port = CoreTransport(NativeCore())
    port.run_ms(10_000)  # running for 10 s: a radio link opens no reset
    port.from_rover = b""
    with pytest.raises(ProvisionError, match="no rover booted .* USB cable"):
        provision(port, KEY, clock=port.clock)
    assert port.sent_to_rover == b""
    assert port.core.take_key_change() is None


def test_a_key_sent_after_the_window_is_refused_by_the_rover():
    port = CoreTransport(NativeCore())
    port.run_ms(6_000)  # its boot HELLO still unread, 6 s later
    with pytest.raises(ProvisionError, match="6 s after its reset, past its 5 s window"):
        provision(port, KEY, clock=port.clock)
    assert port.core.take_key_change() is None


def test_erase_of_a_rover_with_no_key_is_taken_as_before():
    port = CoreTransport(NativeCore())
    assert provision(port, None, clock=port.clock).startswith("the rover's link key is erased")
    assert port.core.take_key_change() == ("erase", None)


@pytest.mark.parametrize("cause", RESET_CAUSES)
def test_a_keyed_rover_refuses_a_new_key_or_an_erase_without_consent_after_any_reset(cause):
    for new in (NEW_KEY, None):
        port = CoreTransport(NativeCore(key=KEY, reset_cause=cause))
        with pytest.raises(NeedsConsent) as info:
            provision(port, new, clock=port.clock)
        assert port.core.take_key_change() is None
        line = str(info.value)
        assert "\n" not in line and "--current-key-file" in line and f"pin D{mg.SIGN_CONSENT_PIN} to GND" in line
        assert info.value.exit_code == 2 and info.value.pin == mg.SIGN_CONSENT_PIN
        # it still obeys the key it holds
        port.from_rover = b""
        port.write(encode_frame(mg.Stop(reason=0), 7, Signer(KEY, mg.SIGN_HOST_TO_ROVER)))
        port.run_ms(100)
        heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST))
        assert [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)] == [7]


@pytest.mark.parametrize("cause", RESET_CAUSES)
def test_a_keyed_rover_takes_a_new_key_signed_with_its_current_one(cause):
    port = CoreTransport(NativeCore(key=KEY, reset_cause=cause))
    line = provision(port, NEW_KEY, clock=port.clock, current_key=KEY)
    assert line.startswith("stored the key") and "current key's signature" in line
    assert port.core.take_key_change() == ("store", NEW_KEY)
    # the frame that went out was signed (a keyed rover takes no other without the pin)
    sent = FrameDecoder(Verifier(KEY, mg.SIGN_HOST_TO_ROVER)).feed(port.sent_to_rover)
    assert [type(f.message) for f in sent] == [mg.Provision] and sent[0].counter is not None


def test_a_keyed_rover_erases_its_key_for_an_erase_signed_with_it():
    port = CoreTransport(NativeCore(key=KEY, reset_cause=0x01))
    assert provision(port, None, clock=port.clock, current_key=KEY).startswith("the rover's link key is erased")
    assert port.core.take_key_change() == ("erase", None)


def test_a_wrong_current_key_is_named_before_anything_is_sent():
    port = CoreTransport(NativeCore(key=KEY))
    with pytest.raises(WrongCurrentKey, match="not the one given with --current-key-file") as info:
        provision(port, NEW_KEY, clock=port.clock, current_key=NEW_KEY)
    assert info.value.exit_code == 2
    assert port.sent_to_rover == b"" and port.core.take_key_change() is None


@pytest.mark.parametrize("cause", RESET_CAUSES)
def test_a_keyed_rover_reset_with_the_consent_pin_held_takes_an_unsigned_key(cause):
    port = CoreTransport(NativeCore(key=KEY, reset_cause=cause | mg.SIGN_CONSENT_RESET_BIT))
    line = provision(port, NEW_KEY, clock=port.clock)
    assert "consent pin (D7) held at its reset: take the jumper off" in line
    assert port.core.take_key_change() == ("store", NEW_KEY)


def test_a_rover_with_no_key_is_given_one_unsigned_even_with_a_current_key_named():
    port = CoreTransport(NativeCore())
    assert provision(port, NEW_KEY, clock=port.clock, current_key=KEY).startswith("stored the key")
    assert port.core.take_key_change() == ("store", NEW_KEY)
    assert all(f.counter is None for f in FrameDecoder().feed(port.sent_to_rover))


def _key_file(path, key: bytes):
    path.write_text(key.hex() + "\n")
    path.chmod(0o600)
    return str(path)


def test_the_command_says_the_two_ways_to_consent_in_one_line_and_exits_2(tmp_path, monkeypatch, capsys):
    import rovernav.link.transport as transport
    from rovernav.cli import main

    monkeypatch.setattr(transport, "open_transport", lambda spec: CoreTransport(NativeCore(key=KEY, reset_cause=1)))
    new = _key_file(tmp_path / "new.key", NEW_KEY)
    assert main(["provision", "--port", "/dev/ttyACM0", "--key-file", new]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith("rovernav provision: the rover holds a link key")
    assert "--current-key-file" in err[0] and "pin D7 to GND" in err[0]

    cores = []

    def rover(spec):
        cores.append(NativeCore(key=KEY, reset_cause=1))
        return CoreTransport(cores[-1])

    monkeypatch.setattr(transport, "open_transport", rover)
    current = _key_file(tmp_path / "current.key", KEY)
    assert main(["provision", "--port", "/dev/ttyACM0", "--key-file", new, "--current-key-file", current]) == 0
    assert cores[-1].take_key_change() == ("store", NEW_KEY)
    assert main(["provision", "--port", "/dev/ttyACM0", "--key-file", new, "--current-key-file", new]) == 2
    assert "not the one given with --current-key-file" in capsys.readouterr().err


def test_the_command_refuses_a_missing_key_file_and_needs_key_or_erase(tmp_path, capsys):
    from rovernav.cli import main

    for argv in (
        ["provision", "--port", "loop://"],
        ["provision", "--port", "loop://", "--key-file", str(tmp_path / "none.key")],
    ):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--key-file" in err and "none.key" in err
    with pytest.raises(SystemExit) as exc:
        main(["provision", "--port", "loop://", "--erase", "--current-key-file", str(tmp_path / "none.key")])
    assert exc.value.code == 2 and "none.key" in capsys.readouterr().err


def test_the_commands_help_names_the_current_key_file_and_the_consent_pin(capsys):
    from rovernav.cli import main

    with pytest.raises(SystemExit):
        main(["provision", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--current-key-file FILE" in out and "pin D7 held to GND" in out


# ---------------------------------------------------------------- the fleet id ([fleet], issue 30)


def _addresses(wire: bytes, msg_id: int | None = None) -> list[int]:
    """The address in every frame's version byte (signed or not, under whatever key); only the
    frames of message `msg_id` when it is given (PROVISION: not the polls that follow it)."""
    raws = [cobs_decode(body) for body in wire.split(b"\x00") if body]
    return [(r[0] & mg.ADDRESS_MASK) >> mg.ADDRESS_SHIFT for r in raws if msg_id is None or r[1] == msg_id]


@pytest.mark.parametrize("fleet_id", [1, 2, 3, 4])
def test_a_rover_is_made_rover_k_of_a_fleet_and_answers_from_its_new_address(fleet_id):
    port = CoreTransport(NativeCore())
    line = provision(port, KEY, clock=port.clock, fleet_id=fleet_id)
    assert line.startswith("stored the key")
    assert f"rover {fleet_id} of a fleet (address {fleet_id - 1}): it speaks only when spoken to" in line
    assert port.core.take_key_change() == ("store", KEY)
    assert port.core.fleet_id == fleet_id
    assert _addresses(port.sent_to_rover, mg.Provision.ID) == [0]  # sent where the rover was: a lone rover
    # ... and polled where it now is: a rover of a fleet answers only when polled ([fleet])
    assert set(_addresses(port.sent_to_rover, mg.Heartbeat.ID)) == {fleet_id - 1}
    # From now on it waits to be spoken to at its new address, and answers from there (its queue
    # full of the STATUS frames it could not say: the host asks again, as it does, until answered).
    port.from_rover = b""
    port.run_ms(2000)
    assert port.from_rover == b""
    signer, heard = (
        Signer(KEY, mg.SIGN_HOST_TO_ROVER),
        FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST), address=fleet_id - 1),
    )
    signer.jump_past(int((time.time() - mg.SIGN_EPOCH_UNIX_S) * 1000) + 10_000)  # past provision's polls
    acked = []
    poll = mg.Heartbeat(host_time_ms=0, camera=0, scan_heard=0, path_id=0)
    for seq in range(5, 10):
        port.write(encode_frame(mg.Stop(reason=0), seq, signer, address=fleet_id - 1))
        port.write(encode_frame(poll, seq + 100, signer, address=fleet_id - 1))  # the slot's poll: its grant
        port.run_ms(100)
        acked += [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)]
        port.from_rover = b""
    assert acked and heard.counters.dropped == 0


def test_a_fleet_rovers_boot_hello_names_its_address_and_provision_sends_there():
    port = CoreTransport(NativeCore(key=KEY, fleet_id=3, reset_cause=1))  # a keyed rover 3 (address 2)
    line = provision(port, NEW_KEY, clock=port.clock, current_key=KEY, fleet_id=0)
    assert "with its current key's signature" in line and "of a fleet" not in line
    assert _addresses(port.sent_to_rover, mg.Provision.ID) == [2]
    assert port.core.take_key_change() == ("store", NEW_KEY)
    assert port.core.fleet_id == 0  # a lone rover again: it talks unasked
    port.from_rover = b""
    port.run_ms(1000)
    assert _addresses(port.from_rover) and set(_addresses(port.from_rover)) == {0}


def test_an_erase_keeps_the_fleet_id_it_is_given():
    port = CoreTransport(NativeCore(fleet_id=2))
    assert "rover 4 of a fleet (address 3)" in provision(port, None, clock=port.clock, fleet_id=4)
    assert port.core.take_key_change() == ("erase", None) and port.core.fleet_id == 4


def test_a_lone_rover_is_provisioned_byte_for_byte_as_before():
    port = CoreTransport(NativeCore())
    provision(port, KEY, clock=port.clock)
    frame = encode_frame(mg.Provision(key=tuple(KEY)), 0)
    assert port.sent_to_rover == frame and port.core.fleet_id == 0


@pytest.mark.parametrize("bad", [-1, 5, True])
def test_provision_refuses_a_fleet_id_outside_0_to_4_before_sending_anything(bad):
    from rovernav.errors import InputError

    port = CoreTransport(NativeCore())
    with pytest.raises(InputError, match=r"fleet id is 0 \(a lone rover\) or 1\.\.4"):
        provision(port, KEY, clock=port.clock, fleet_id=bad)
    assert port.sent_to_rover == b""


def test_the_command_takes_fleet_id_and_refuses_one_outside_0_to_4_in_one_line(tmp_path, monkeypatch, capsys):
    import rovernav.link.transport as transport
    from rovernav.cli import main

    cores = []

    def rover(spec):
        cores.append(NativeCore(reset_cause=2))
        return CoreTransport(cores[-1])

    monkeypatch.setattr(transport, "open_transport", rover)
    key = _key_file(tmp_path / "k.key", KEY)
    assert main(["provision", "--port", "/dev/ttyACM0", "--key-file", key, "--fleet-id", "2"]) == 0
    assert cores[-1].fleet_id == 2 and "rover 2 of a fleet (address 1)" in capsys.readouterr().out
    for bad in ("5", "-1", "two"):
        with pytest.raises(SystemExit) as exc:
            main(["provision", "--port", "/dev/ttyACM0", "--key-file", key, "--fleet-id", bad])
        assert exc.value.code == 2
        err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        assert len(err) == 1 and "--fleet-id" in err[0] and "a fleet id is 0 (a lone rover) or 1..4" in err[0]
    assert len(cores) == 1  # nothing opened for a bad fleet id
    with pytest.raises(SystemExit):
        main(["provision", "--help"])
    assert "--fleet-id K" in " ".join(capsys.readouterr().out.split())
