"""The simulated radio's model: its parameters (`ChannelConfig`), the limits of what a user may
set, and `radio_config`, which checks the settings in users' units and makes the ChannelConfig.

The simulator's radio (rovernav.sim.channel) runs this model; the configuration's [radio] table
(rovernav.config) and the --radio-* flags of `rovernav sim` and `rovernav trials` are checked
here, so that neither the configuration nor the simulator needs the other for it.

What can be set (`ChannelConfig`; `rovernav sim`'s --radio-* flags and the [radio] table):

byte_loss   the long-run mean share of the bytes sent that are lost. Without bursts each byte is
            lost independently with that probability (as before bursts existed).
bit_error   the long-run mean share of the bytes sent that arrive with one bit flipped (a byte
            is lost or corrupted, never both: the bytes that get through are corrupted with
            probability bit_error / (1 - byte_loss), the same as bit_error when nothing is lost).
bursts      a two-state Gilbert-Elliott process (sim/channel.py's `BurstProcess`): good and
            burst states whose sojourns are exponential in simulated time, with mean
            burst_mean_s in a burst and burst_mean_s x (1 - share) / share between bursts, so
            the long-run share of time in bursts is burst_share. With bursts, bytes are lost and
            corrupted ONLY inside them, at byte_loss / burst_share and bit_error / burst_share
            (so the means stay those set); that must not pass 1. Bit errors are concentrated in
            the bursts as losses are: both come from the same fade or interferer, and between
            bursts the link is clean.
            ONE process serves both directions: a burst is the path between the two antennas
            fading, or interference at the rover's site (its own motors, another 433 MHz
            transmitter nearby), and the path is reciprocal, so when the rover cannot hear the
            host the host mostly cannot hear the rover either, as the rover's LINK_LOST logic
            assumes. (Each direction still draws its own byte losses within a burst.)
jitter_s    a per-frame extra delay, exponential with this mean, drawn when a frame's first byte
            goes on the air. Order is kept: no byte arrives before one sent before it (a serial
            modem is a FIFO), so a late frame also holds up the frames queued behind it.
half_duplex both directions share one 57,600-baud medium (sim/channel.py's `Medium`), as 433 MHz
            transparent serial modems (HC-12, APC220, 3DR-style) do: a byte on the air from one
            end while the other's is on the air collides, and both are lost (no carrier sense:
            either end sends when its serial port has bytes). Off by default: today's figures
            were made full duplex (two independent 57,600-baud directions), and the default
            keeps them comparable.
"""

from __future__ import annotations

import dataclasses
import math

from .errors import InputError
from .vehicle_gen import LINK_BAUD

#: Limits of what a user may set (flags and the [radio] table).
MAX_BURST_MEAN_S = 3600.0
MIN_BURST_MEAN_S = 0.001  # a burst shorter than a few bytes is just independent loss
MAX_JITTER_MS = 5000.0


@dataclasses.dataclass(frozen=True)
class ChannelConfig:
    baud: int = LINK_BAUD  # protocol/vehicle.toml
    delay_s: float = 0.015  # radio modem latency, one way
    byte_loss: float = 0.0  # long-run mean share of the bytes sent that are lost
    bit_error: float = 0.0  # long-run mean share of the bytes sent that arrive with one bit flipped
    burst_mean_s: float = 0.0  # mean burst length [s]; 0: no bursts (loss and bit errors independent)
    burst_share: float = 0.0  # long-run share of time in bursts, in (0, 1) with bursts
    jitter_s: float = 0.0  # mean extra delay per frame [s] (exponential); 0: none
    half_duplex: bool = False  # both directions share one medium: simultaneous bytes collide

    @property
    def bytes_per_s(self) -> float:
        return self.baud / 10.0  # 8N1: ten bits a byte

    @property
    def bursts(self) -> bool:
        """Whether a burst process runs: bursts set, and something for them to do."""
        return self.burst_mean_s > 0 and self.burst_share > 0 and bool(self.byte_loss or self.bit_error)

    def settings(self) -> dict:
        """The settings in the units users give them (report.json, the run log, trials.json)."""

        def pct(v: float) -> float:  # percent, without float noise
            return round(v * 100, 9)

        burst = None
        if self.burst_mean_s > 0 and self.burst_share > 0:
            burst = {
                "mean_s": self.burst_mean_s,
                "share": self.burst_share,
                "loss_in_burst_pct": pct(self.byte_loss / self.burst_share),
                "ber_in_burst_pct": pct(self.bit_error / self.burst_share),
                "bit_errors": "in bursts only, as losses",
                "process": "one Gilbert-Elliott process shared by both directions",
            }
        return {
            "baud": self.baud,
            "delay_ms": round(self.delay_s * 1000, 9),
            "loss_pct": pct(self.byte_loss),
            "ber_pct": pct(self.bit_error),
            "burst": burst,
            "jitter_ms": round(self.jitter_s * 1000, 9),
            "jitter": "exponential per frame, order kept" if self.jitter_s > 0 else None,
            "half_duplex": self.half_duplex,
        }


# ---------------------------------------------------------------- what users set

#: The names of the settings as `rovernav sim` and `rovernav trials` take them.
FLAG_NAMES = {
    "loss_pct": "--radio-loss",
    "ber_pct": "--radio-ber",
    "burst_mean_s": "--radio-burst MEAN_S",
    "burst_share": "--radio-burst SHARE",
    "jitter_ms": "--radio-jitter-ms",
    "half_duplex": "--radio-half-duplex",
}


def radio_config(
    loss_pct: float = 0.0,
    ber_pct: float = 0.0,
    burst_mean_s: float = 0.0,
    burst_share: float = 0.0,
    jitter_ms: float = 0.0,
    half_duplex: bool = False,
    *,
    names: dict | None = None,
    base: ChannelConfig = ChannelConfig(),
) -> ChannelConfig:
    """A ChannelConfig from the settings in users' units, or InputError (one line) naming what is
    wrong by `names` (setting -> its flag or key; the flags by default). Each value is checked on
    its own (finite, in range) and together: bursts need a mean > 0 and a share in (0, 1), and the
    loss and bit errors inside a burst, (loss + ber) / share, cannot pass 100 %."""
    n = FLAG_NAMES | (names or {})

    def finite(key: str, value: float, lo: float, hi: float, what: str) -> float:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
            or not lo <= value <= hi
        ):
            raise InputError(f"{n[key]}: {what} must be a number from {lo:g} to {hi:g}, got {value!r}")
        return float(value)

    loss = finite("loss_pct", loss_pct, 0.0, 100.0, "the mean byte loss (%)")
    ber = finite("ber_pct", ber_pct, 0.0, 100.0, "the share of bytes with a bit flipped (%)")
    jitter = finite("jitter_ms", jitter_ms, 0.0, MAX_JITTER_MS, "the mean extra delay per frame (ms)")
    mean = finite("burst_mean_s", burst_mean_s, 0.0, MAX_BURST_MEAN_S, "the mean burst length (s)")
    share = finite("burst_share", burst_share, 0.0, 1.0, "the share of time in bursts")
    if mean or share:  # bursts: both set
        if not MIN_BURST_MEAN_S <= mean:
            raise InputError(
                f"{n['burst_mean_s']}: with bursts, the mean burst length must be from "
                f"{MIN_BURST_MEAN_S:g} to {MAX_BURST_MEAN_S:g} s, got {mean:g}"
            )
        if not 0.0 < share < 1.0:
            raise InputError(
                f"{n['burst_share']}: with bursts, the share of time in them must be above 0 and below 1, got {share:g}"
            )
    if loss + ber > 100.0 + 1e-9:
        raise InputError(
            f"{n['loss_pct']} {loss:g} % and {n['ber_pct']} {ber:g} %: a byte is lost or corrupted, "
            f"not both, so together they cannot pass 100 %"
        )
    if share and (loss + ber) / 100.0 > share * (1 + 1e-12):
        what = " and ".join(f"{n[k]} {v:g} %" for k, v in (("loss_pct", loss), ("ber_pct", ber)) if v)
        raise InputError(
            f"{what} with {n['burst_share']} {share:g}: bytes are lost or corrupted only inside "
            f"bursts, at {(loss + ber) / share:g} % there, more than 100 %; with bursts "
            f"{100 * share:g} % of the time, loss and bit errors can be at most {100 * share:g} % in all"
        )
    if not isinstance(half_duplex, bool):
        raise InputError(f"{n['half_duplex']}: true or false, got {half_duplex!r}")
    return dataclasses.replace(
        base,
        byte_loss=loss / 100.0,
        bit_error=ber / 100.0,
        burst_mean_s=mean,
        burst_share=share,
        jitter_s=jitter / 1000.0,
        half_duplex=half_duplex,
    )
