"""The simulated radio's command-line flags (`rovernav sim`, `rovernav trials`): --radio-loss,
--radio-ber, --radio-burst, --radio-jitter-ms and --radio-half-duplex, read over a configuration's
[radio] table into the settings rovernav/radio.py checks, and the line a run's report says of them."""

from __future__ import annotations

import argparse
import math

from .validate import number
from .vehicle_gen import LINK_BAUD


def burst_spec(text: str) -> tuple[float, float]:
    """An argparse type: MEAN_S:SHARE for --radio-burst (or "off": no bursts)."""
    from .radio import MAX_BURST_MEAN_S, MIN_BURST_MEAN_S

    if text.strip().lower() in ("off", "none"):
        return 0.0, 0.0
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        mean, share = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected MEAN_S:SHARE, e.g. 0.5:0.1 (bursts of 0.5 s on average, 10 % of the time), or off"
        ) from None
    if not (math.isfinite(mean) and MIN_BURST_MEAN_S <= mean <= MAX_BURST_MEAN_S):
        raise argparse.ArgumentTypeError(
            f"{text!r}: MEAN_S, the mean burst length, must be from "
            f"{MIN_BURST_MEAN_S:g} to {MAX_BURST_MEAN_S:g} seconds"
        )
    if not (math.isfinite(share) and 0.0 < share < 1.0):
        raise argparse.ArgumentTypeError(f"{text!r}: SHARE, the share of time in bursts, must be above 0 and below 1")
    return mean, share


def add_radio_flags(p: argparse.ArgumentParser, config: bool = True) -> None:
    """The simulated radio's flags (`rovernav sim`, `rovernav trials`); see rovernav/radio.py.
    `config`: the command takes --config, whose [radio] table the flags win over."""
    import textwrap

    from .radio import MAX_BURST_MEAN_S, MAX_JITTER_MS, MIN_BURST_MEAN_S

    g = p.add_argument_group(
        "the simulated radio",
        textwrap.fill(
            width=100,
            text=f"{LINK_BAUD:,} baud 8N1 ({LINK_BAUD // 10:,} bytes/s each way), 15 ms modem latency. By default it "
            "loses and corrupts nothing, is full duplex and has no jitter"
            + (
                "; a configuration's [radio] table (loss_pct, ber_pct, burst_mean_s, burst_share, jitter_ms, "
                "half_duplex) sets the same, and these flags win over it"
                if config
                else ""
            )
            + (
                ". report.json's \"radio\" and the run log's /sim/radio give"
                if config
                else '. Each run\'s report.json "radio" gives'
            )
            + " what it did, each way: bytes sent, lost and corrupted, frames sent and damaged by message kind.",
        ),
    )
    g.add_argument(
        "--radio-loss",
        type=number(0.0, 100.0),
        default=None,
        metavar="PCT",
        help="the long-run mean share of bytes lost, in percent, 0 to 100 (default 0). Each byte "
        "independently, or with --radio-burst only inside bursts",
    )
    g.add_argument(
        "--radio-ber",
        type=number(0.0, 100.0),
        default=None,
        metavar="PCT",
        help="the long-run mean share of bytes that arrive with one bit flipped, in percent, 0 to 100 "
        "(default 0); a byte is lost or corrupted, not both, so with --radio-loss at most 100 "
        "in all. Independently, or with --radio-burst only inside bursts as losses are",
    )
    g.add_argument(
        "--radio-burst",
        type=burst_spec,
        default=None,
        metavar="MEAN_S:SHARE",
        help="losses and bit errors come in bursts (a two-state Gilbert-Elliott channel): bursts last "
        f"MEAN_S seconds on average ({MIN_BURST_MEAN_S:g} to {MAX_BURST_MEAN_S:g}) and take "
        "SHARE of the time (above 0, below 1), both exponential in simulated time; inside a "
        "burst bytes are lost at LOSS / SHARE and corrupted at BER / SHARE, so LOSS + BER may "
        "not pass 100 x SHARE. One burst process for both directions (a fade of the path, or "
        "interference at the rover, hits both ways). off: none (the default)",
    )
    g.add_argument(
        "--radio-jitter-ms",
        type=number(0.0, MAX_JITTER_MS),
        default=None,
        metavar="MS",
        help=f"a mean extra delay per frame, in milliseconds, 0 to {MAX_JITTER_MS:g} (default 0): "
        "exponential, drawn per frame, on top of the 15 ms latency; bytes keep their order (a "
        "late frame holds up those behind it, as in a serial modem)",
    )
    g.add_argument(
        "--radio-half-duplex",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"both ends share one {LINK_BAUD:,}-baud medium, as 433 MHz transparent modems (HC-12, APC220, "
        "3DR-style) do: bytes on the air from both ends at once collide and both are lost (no "
        f"carrier sense). Default off (full duplex, each direction its own {LINK_BAUD:,} baud, as the "
        "figures so far were made, so that they stay comparable); --no-radio-half-duplex "
        "overrides a configuration that turns it on",
    )


def radio_values(args: argparse.Namespace, file=None, where: str = "") -> tuple[dict, dict]:
    """The simulated radio's settings, as radio_config takes them, from the --radio-* flags over a
    configuration's [radio] table (`file`, a RadioConfig; None: the defaults), and the name of each
    as the user gave it (its flag, else its key in the file `where` names)."""
    from .config import RadioConfig
    from .radio import FLAG_NAMES

    file = file or RadioConfig()
    burst = args.radio_burst or (None, None)
    given = {
        "loss_pct": args.radio_loss,
        "ber_pct": args.radio_ber,
        "burst_mean_s": burst[0],
        "burst_share": burst[1],
        "jitter_ms": args.radio_jitter_ms,
        "half_duplex": args.radio_half_duplex,
    }
    values = {k: getattr(file, k) if v is None else v for k, v in given.items()}
    names = {k: FLAG_NAMES[k] if v is not None or not where else f"{where}[radio] {k}" for k, v in given.items()}
    return values, names


def radio_from_args(args: argparse.Namespace, file=None, where: str = ""):
    """The ChannelConfig of the flags over the file (see radio_values), or InputError (one line)
    naming the flag or key at fault."""
    from .radio import radio_config

    values, names = radio_values(args, file, where)
    return radio_config(**values, names=names)


def radio_line(report: dict) -> str | None:
    """One line on the radio, for a run whose radio was set to anything but the defaults."""
    r = report.get("radio")
    if not r:
        return None
    st = r["settings"]
    if not (st["loss_pct"] or st["ber_pct"] or st["burst"] or st["jitter_ms"] or st["half_duplex"]):
        return None
    parts = [f"loss {st['loss_pct']:g} %", f"BER {st['ber_pct']:g} %"]
    if st["burst"]:
        parts.append(f"bursts {st['burst']['mean_s']:g} s, {100 * st['burst']['share']:g} % of the time")
    if st["jitter_ms"]:
        parts.append(f"jitter {st['jitter_ms']:g} ms")
    if st["half_duplex"]:
        parts.append("half duplex")
    ways = []
    for way, label in (("to_rover", "to the rover"), ("to_host", "to the host")):
        c = r[way]
        ways.append(
            f"{label} {c['frames_damaged']}/{c['frames_sent']} frames damaged "
            f"({c['bytes_lost']} bytes lost, {c['bytes_corrupted']} corrupted)"
        )
    return f"  radio ({', '.join(parts)}): " + "; ".join(ways)
