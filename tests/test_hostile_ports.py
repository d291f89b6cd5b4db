"""Hostile transport specs: every bad `--port`/`[link] port` spec is a one-line InputError or
LinkError (exit 2 from `rovernav link-check`), never a traceback, and a port that is not a
serial port is said to be one. (Split from test_hostile_link.py.)"""

from __future__ import annotations

import os

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovernav import cli
from rovernav.errors import InputError
from rovernav.link.errors import LinkError, PortError, PortSpecError
from rovernav.link.transport import LoopbackTransport, PtyTransport, open_transport, parse_serial_spec

# ------------------------------------------------------------------ case 2: transport specs


@pytest.mark.parametrize(
    "spec, shown",
    [
        ("", "empty transport spec"),
        ("   ", "empty transport spec"),
        ("\t", "empty transport spec"),
        ("COM4\tx", "control character"),
        ("loop://x", "unknown transport 'loop://x'"),
        ("pty://?", "unknown transport 'pty://?'"),
        ("tcp://rover:1", "unknown transport"),
        ("/dev/ttyUSB0\n", "control character"),
        ("/dev/tty\x00USB0", "control character"),
        ("COM4\x7f", "control character"),
        ("/dev/ttyUSB0@", "bad baud rate ''"),
        ("/dev/ttyUSB0@9" * 3, "bad baud rate"),
        ("/dev/ttyUSB0@1", "bad baud rate '1'"),
        ("/dev/ttyUSB0@99999999999", "bad baud rate"),
        ("/dev/ttyUSB0@5_7600", "bad baud rate"),
        ("/dev/ttyUSB0@ 57600", "bad baud rate"),
        ("/dev/ttyUSB0@٥٧٦٠٠", "bad baud rate"),
        ("@57600", "no port name"),
        ("x" * 5000, "at most 1024"),
        (None, "must be a string"),
        (57600, "must be a string"),
        (b"/dev/ttyUSB0", "must be a string"),
    ],
)
def test_a_bad_transport_spec_is_a_one_line_input_error_naming_it(spec, shown):
    with pytest.raises(PortSpecError) as info:
        open_transport(spec)  # type: ignore[arg-type]
    message = str(info.value)
    assert shown in message and "\n" not in message
    assert isinstance(info.value, InputError) and isinstance(info.value, LinkError)
    assert isinstance(info.value, ValueError)  # as the transport's argument errors always were


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="needs /dev/null")
@pytest.mark.parametrize("spec", ["/dev/null", "/dev/null@115200", "/"])
def test_a_port_that_exists_but_is_not_a_serial_port_is_a_port_error_saying_so(spec):
    with pytest.raises(PortError, match="not a serial port") as info:
        open_transport(spec)
    assert "\n" not in str(info.value)


def test_a_run_refuses_a_loopback_or_pty_spec_as_a_serial_port():
    for spec in ("loop://", "pty://"):
        with pytest.raises(PortSpecError, match="not a serial port"):
            parse_serial_spec(spec)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["link-check", "--port", "loop://x"], "unknown transport 'loop://x'"),
        (["link-check", "--port", "pty://?"], "unknown transport 'pty://?'"),
        (["link-check", "--port", "/dev/ttyUSB0@0"], "bad baud rate '0'"),
        (["link-check", "--port", "/dev/null", "--timeout", "0.2"], "not a serial port"),
        (["link-check", "--port", "", "--timeout", "0.2"], "empty port"),
        (["link-check", "--port", "loop://", "--timeout", "nan"], "--timeout"),
    ],
)
def test_link_check_answers_a_bad_port_in_one_line_with_exit_2(argv, words, capsys):
    if "/dev/null" in argv and not os.path.exists("/dev/null"):
        pytest.skip("needs /dev/null")
    try:
        rc = cli.main(argv)
    except SystemExit as exc:  # argparse's own refusals
        rc = exc.code
    err = capsys.readouterr().err.strip()
    assert rc == 2 and words in err and len(err.splitlines()) == 1 and "Traceback" not in err


_NASTY_SPECS = [
    "loop://",
    "pty://",
    "loop:// ",
    " pty://",
    "loop:///",
    "LOOP://",
    "://",
    "@",
    "@@",
    "a@b@c",
    "/dev/ttyNOPE@57600@",
    "COM0",
    "\\\\.\\COM300",
    ".",
    "/",
    "..@9600",
    "\x1b[2J",
    "\u202e",
]


def _safe(spec) -> bool:
    """Not a real terminal device: never open (and reconfigure) one of this machine's ttys."""
    if not isinstance(spec, str):
        return True
    name = spec.strip().rpartition("@")[0] or spec.strip()
    try:
        import stat

        return not (os.path.exists(name) and stat.S_ISCHR(os.stat(name).st_mode) and name != "/dev/null")
    except (OSError, ValueError):
        return True


@settings(max_examples=300, deadline=None)
@given(
    st.one_of(
        st.text(max_size=40),
        st.sampled_from(_NASTY_SPECS),
        st.builds(lambda a, b: f"{a}@{b}", st.text(max_size=12), st.text(max_size=12)),
        st.builds(lambda a, b: f"{a}://{b}", st.text(max_size=8), st.text(max_size=8)),
        st.builds(lambda n: f"/dev/ttyROVERNAV_NONE@{n}", st.integers(-(10**12), 10**12)),
        st.none(),
        st.integers(),
        st.floats(),
        st.binary(max_size=10),
    )
)
def test_any_transport_spec_opens_or_raises_only_an_input_or_link_error(spec):
    if not _safe(spec):
        return
    try:
        t = open_transport(spec)  # type: ignore[arg-type]
    except (InputError, LinkError) as exc:
        assert "\n" not in str(exc) and str(exc)
        return
    t.close()
    assert isinstance(t, (LoopbackTransport, PtyTransport))
