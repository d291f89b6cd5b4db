"""The figures of a soak (link/soak.py): frames lost each way against what missions tolerate, the
round trip, the path loads and the silences; the verdict, the --json summary, the progress line
and the report. `SoakFigures` reads the counts `Soak` keeps as it exchanges frames."""

from __future__ import annotations

import math

from .soak_loss import FAILING_BYTE_LOSS, TOLERATED_BYTE_DAMAGE, byte_damage_for, frame_loss_at
from .soak_plan import FEW_FRAMES, PATH_GIVE_UP_S, PATH_WAYPOINTS, PROBE_HZ, PROBE_PARAM, SILENT_S, WAYS


def _percentile(sorted_values, q: float) -> float | None:
    """Nearest-rank percentile of an ascending sequence (None when empty)."""
    if not sorted_values:
        return None
    return sorted_values[max(0, math.ceil(q / 100.0 * len(sorted_values)) - 1)]


def _median(sorted_values) -> float | None:
    n = len(sorted_values)
    if n == 0:
        return None
    return sorted_values[n // 2] if n % 2 else (sorted_values[n // 2 - 1] + sorted_values[n // 2]) / 2


class SoakFigures:
    """What a soak's counts show; a base of `Soak` (link/soak.py), whose attributes it reads: link,
    quality, tx_lengths, rx_lengths, round_trips, probes_sent, load_times, loads_*, chunks_*,
    longest_silence_s, silences, restarts, rover_boot_id, seconds, elapsed_s, ended_by."""

    def _way(self, which: str) -> dict:
        d = self.quality.to_rover if which == "host_to_rover" else self.quality.to_host
        received = which == "rover_to_host"
        lengths = dict(self.rx_lengths if received else self.tx_lengths)
        lost = None if d.rate is None else 1.0 - d.rate
        frames = sum(lengths.values())
        out = {
            "frames_sent": d.sent,
            "frames_arrived": min(d.arrived, d.sent),
            "lost_share": None if lost is None else round(lost, 5),
            "byte_damage_equivalent": _round(byte_damage_for(lost, lengths, received), 5),
            "tolerated_lost_share": _round(frame_loss_at(TOLERATED_BYTE_DAMAGE, lengths, received), 4),
            "failing_lost_share": _round(frame_loss_at(FAILING_BYTE_LOSS, lengths, received), 4),
            "mean_frame_bytes": round(sum(n * c for n, c in lengths.items()) / frames, 1) if frames else None,
        }
        if not received:
            out["rover_received_broken"] = self.quality.rover_broken
        return out

    def verdict(self) -> tuple[str, str]:
        """(kind, one line): 'ok' (within what missions are shown to tolerate), 'beyond' (past it,
        short of where they fail), 'failing' (past that), or 'unknown' (a way not measured)."""
        ways = {w: self._way(w) for w in WAYS}
        unmeasured = [WAYS[w] for w, f in ways.items() if f["lost_share"] is None or f["tolerated_lost_share"] is None]
        if unmeasured:
            why = (
                "the rover sent no two STATUS to count by"
                if "host -> rover" in unmeasured
                else "too few frames came from the rover"
            )
            return "unknown", f"advice: frames lost {' and '.join(unmeasured)} not measured ({why}): soak longer"

        def pct(v: float) -> str:
            return f"{100 * v:.1f} %"

        worst = max(ways, key=lambda w: ways[w]["lost_share"] / max(ways[w]["tolerated_lost_share"], 1e-9))
        f = ways[worst]
        few = [WAYS[w] for w, g in ways.items() if g["frames_sent"] < FEW_FRAMES]
        rough = f" (few frames {' and '.join(few)}: a longer soak measures more closely)" if few else ""
        fix = (
            "move the radio (higher, in sight of the rover, away from the motors and the Uno's wires), "
            "change the channel, check both antennas and that both radios use the same air rate, then soak again"
        )
        failing = [w for w, g in ways.items() if g["lost_share"] > g["failing_lost_share"]]
        if failing:
            what = " and ".join(
                f"{pct(ways[w]['lost_share'])} of frames lost {WAYS[w]}, above the {pct(ways[w]['failing_lost_share'])}"
                for w in failing
            )
            return "failing", (
                f"advice: {what} at which missions fail (5 % of bytes lost, for these frames): {fix}{rough}"
            )
        if f["lost_share"] > f["tolerated_lost_share"]:
            return "beyond", (
                f"advice: {pct(f['lost_share'])} of frames lost {WAYS[worst]}, beyond the "
                f"{pct(f['tolerated_lost_share'])} missions are shown to tolerate (1 % of bytes lost "
                f"and 0.1 % corrupted, for these frames; they fail from "
                f"{pct(f['failing_lost_share'])}): missions may run slow or fail; {fix}{rough}"
            )
        t = {w: pct(g["tolerated_lost_share"]) for w, g in ways.items()}
        return "ok", (
            f"verdict: within what missions are shown to tolerate (up to {t['host_to_rover']} of "
            f"frames lost host -> rover and {t['rover_to_host']} rover -> host: 1 % of bytes lost "
            f"and 0.1 % corrupted, for these frames){rough}"
        )

    def summary(self) -> dict:
        """Every figure, for --json (seconds in seconds, shares in [0, 1], None where not measured)."""
        rt = sorted(self.round_trips)
        loads = sorted(self.load_times)
        kind, line = self.verdict()
        hello = self.link.peer_hello
        return {
            "seconds_asked": self.seconds,
            "seconds_run": round(self.elapsed_s, 3),
            "ended_by": self.ended_by,
            "signed": self.link.signer is not None,
            "rover": {
                "boot_id": self.rover_boot_id,
                "restarts": self.restarts,
                "firmware": None if hello is None else f"{hello.firmware_version >> 8}.{hello.firmware_version & 0xFF}",
            },
            **{w: self._way(w) for w in WAYS},
            "round_trip_s": {
                "probe": f"CONFIG of parameter {PROBE_PARAM} (none) -> NACK unknown_param",
                "sent": self.probes_sent,
                "answered": len(rt),
                "unanswered": self._unanswered(),
                "median": _round(_median(rt), 4),
                "p99": _round(_percentile(rt, 99), 4),
                "worst": _round(rt[-1] if rt else None, 4),
            },
            "path_load_s": {
                "waypoints": PATH_WAYPOINTS,
                "started": self.loads_started,
                "completed": len(loads),
                "given_up": self.loads_given_up,
                "refused": len(self.loads_refused),
                "skipped_mission_running": self.loads_skipped,
                "median": _round(_median(loads), 3),
                "worst": _round(loads[-1] if loads else None, 3),
                "chunks_sent": self.chunks_sent,
                "chunks_sent_again": self.chunks_resent,
            },
            "longest_silence_s": round(self.longest_silence_s, 3),
            "silences_over_1s": self.silences,
            "verdict": kind,
            "advice": line if line.startswith("advice:") else None,
            "verdict_line": line,
        }

    def _unanswered(self) -> int:
        """Probes sent and not answered (those still within PROBE_TIMEOUT_S at the end left out)."""
        return self.probes_sent - len(self.round_trips) - len(self._probes)

    def progress_line(self) -> str:
        rt = sorted(self.round_trips)
        med = _median(rt)
        loads = len(self.load_times)
        return (
            f"soak {self.elapsed_s:.0f}/{self.seconds:g} s: {self.quality.line()} (last 10 s); round trip "
            f"{'-' if med is None else f'{1000 * med:.0f} ms'} median of {len(rt)}; {loads} path"
            f"{'' if loads == 1 else 's'} loaded"
        )

    def report_lines(self) -> list[str]:
        s = self.summary()
        out = []
        ended = "" if s["ended_by"] is None else f", ended early ({s['ended_by']})"
        out.append(
            f"soak: {s['seconds_run']:.1f} of {s['seconds_asked']:g} s{ended}; "
            f"{'signed' if s['signed'] else 'unsigned'} frames"
            + (
                f"; the rover restarted {self.restarts} time{'s' if self.restarts != 1 else ''}"
                if self.restarts
                else ""
            )
        )
        for w, name in WAYS.items():
            f = s[w]
            if f["lost_share"] is None:
                out.append(f"  frames lost {name}: not measured")
                continue
            how = (
                "by the rover's STATUS rx_ok against the frames sent"
                + (
                    f"; it counted {f['rover_received_broken']} arriving broken"
                    if f.get("rover_received_broken")
                    else ""
                )
                if w == "host_to_rover"
                else "by gaps in the rover's sequence numbers"
            )
            out.append(
                f"  frames lost {name}: {100 * f['lost_share']:.2f} % "
                f"({f['frames_sent'] - f['frames_arrived']:,} of {f['frames_sent']:,}, {how}); as if "
                f"{100 * f['byte_damage_equivalent']:.2f} % of bytes were lost (frames of "
                f"{f['mean_frame_bytes']:g} bytes on average)"
            )
        r = s["round_trip_s"]
        if r["answered"]:
            out.append(
                f"  round trip (CONFIG probe -> NACK, {PROBE_HZ:g} a second): median {1000 * r['median']:.0f} ms, "
                f"99th percentile {1000 * r['p99']:.0f} ms, worst {1000 * r['worst']:.0f} ms; "
                f"{r['answered']:,} of {r['sent']:,} answered, {r['unanswered']:,} lost one way or the other"
            )
        else:
            out.append(f"  round trip: none of {r['sent']:,} probes answered")
        p = s["path_load_s"]
        if p["completed"]:
            out.append(
                f"  {PATH_WAYPOINTS}-waypoint path load: median {p['median']:.2f} s, worst {p['worst']:.2f} s "
                f"over {p['completed']} loads; {p['chunks_sent_again']} of {p['chunks_sent']} chunks sent again"
                + (f"; {p['given_up']} given up after {PATH_GIVE_UP_S:g} s" if p["given_up"] else "")
                + (f"; {p['refused']} refused ({self.loads_refused[0]})" if p["refused"] else "")
                + (
                    f"; {p['skipped_mission_running']} not sent while the rover was running a mission"
                    if p["skipped_mission_running"]
                    else ""
                )
            )
        elif p["skipped_mission_running"]:
            out.append("  path load: not measured: the rover is running a mission (it would follow a path sent now)")
        else:
            out.append(
                f"  {PATH_WAYPOINTS}-waypoint path load: none completed ({p['started']} started, "
                f"{p['given_up']} given up after {PATH_GIVE_UP_S:g} s, {p['refused']} refused)"
            )
        out.append(
            f"  longest silence from the rover: {s['longest_silence_s']:.2f} s"
            + (f" ({s['silences_over_1s']} of {SILENT_S:g} s or more)" if s["silences_over_1s"] else "")
        )
        out.append(s["verdict_line"])
        return out


def _round(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)
