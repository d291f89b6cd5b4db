"""`rovernav provision` against the rover's firmware core (its C ABI), in simulated time: the key
is sent only after the rover is seen to boot, and the rover takes it only soon after a reset."""
from __future__ import annotations

import pytest

from rovernav.firmware import RoverCore
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder, Signer, Verifier, encode_frame
from rovernav.link.provision import ProvisionError, provision

from tests.core_transport import CoreTransport

KEY = bytes(range(50, 66))


def test_a_rover_that_has_just_booted_takes_the_key_and_answers_signed_with_it():
    port = CoreTransport(RoverCore())              # opening the USB port reset it: it boots now
    line = provision(port, KEY, clock=port.clock)
    assert line.startswith("stored the key")
    assert port.core.take_key_change() == ("store", KEY)
    # From now on it takes only what this key signs, and signs what it says.
    port.from_rover = b""
    heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST))
    port.write(encode_frame(mg.Stop(reason=0), 1))                                        # unsigned
    port.write(encode_frame(mg.Stop(reason=0), 2, Signer(KEY, mg.SIGN_HOST_TO_ROVER)))   # signed
    port.run_ms(100)
    said = [f.message for f in heard.feed(port.from_rover)]
    assert [m.seq for m in said if isinstance(m, mg.Ack)] == [2]
    assert port.core.auth_counters()["not_signed"] == 1 and heard.counters.dropped == 0


def test_over_a_port_that_did_not_reset_the_rover_nothing_is_sent():
    port = CoreTransport(RoverCore())
    port.run_ms(10_000)                            # running for 10 s: a radio link opens no reset
    port.from_rover = b""
    with pytest.raises(ProvisionError, match="no rover booted .* USB cable"):
        provision(port, KEY, clock=port.clock)
    assert port.sent_to_rover == b""
    assert port.core.take_key_change() is None


def test_a_key_sent_after_the_window_is_refused_by_the_rover():
    port = CoreTransport(RoverCore())
    port.run_ms(6_000)                             # its boot HELLO still unread, 6 s later
    with pytest.raises(ProvisionError, match="6 s after its reset, past its 5 s window"):
        provision(port, KEY, clock=port.clock)
    assert port.core.take_key_change() is None


def test_erase_forgets_the_key():
    port = CoreTransport(RoverCore(key=KEY))
    assert provision(port, None, clock=port.clock).startswith("the rover's link key is erased")
    assert port.core.take_key_change() == ("erase", None)


def test_the_command_refuses_a_missing_key_file_and_needs_key_or_erase(tmp_path, capsys):
    from rovernav.cli import main

    for argv in (["provision", "--port", "loop://"],
                 ["provision", "--port", "loop://", "--key-file", str(tmp_path / "none.key")]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--key-file" in err and "none.key" in err
