"""Where the Uno image's steps spend their cycles, by function: uno_timing["profile"].

The harness (tools/avrsim/unocore.c, "Profile") counts every instruction executed while PB0 is
high, by the function whose symbol holds its PC (`rovernav.cores.elf.function_map`), for every
kind of step (all, with a FIX, with sonar, ...) and keeps the longest steps' own counts; this
module starts the count (`start_profile`) and turns it into the report (`read_profile`).
`rovernav sim --rover uno --profile` (`UnoCore(profile=True)`) asks for it.
"""

from __future__ import annotations

import ctypes
import math
import re
from pathlib import Path

from .elf import VECTORS_328P, FunctionMap, function_map, short_name
from .uno_harness import CLOCK_HZ, DESC_FLAGS, PROF_KINDS, UnoSetupError, _ProfEntry, _ProfInfo, _ProfStep

# avr-libc's float routines (libm, libgcc's soft float on the AVR) and libgcc's integer helpers
FLOAT_LIBRARY = re.compile(
    r"^(__(add|sub|mul|div|neg)sf3\w*|__fp_\w+|__fix(uns)?sfsi|__float(un)?sisf|__(cmp|eq|ne|lt|le|gt|ge|unord)sf2"
    r"|a?sinh?|a?cosh?|a?tanh?|atan2|sqrt|cbrt|hypot|fabs|l?l?round|l?rint|floor|ceil|trunc|fmod|modf|exp|log|log10"
    r"|pow|ldexp|frexp|square|inverse|fmin|fmax|fdim|fma|copysign|signbit|isinf|isnan|isfinite)$"
)
INTEGER_LIBRARY = re.compile(
    r"^__(u?(mul|div|mod|divmod)[qhsd]i[34]\w*|u?mulh?isi3|umulhisi3|usmulhisi3|"
    r"mulshisi3|muluhisi3|mulsidi3|umulsidi3|negsi2|ashl|ashr|lshr|cmpdi2|prologue_saves__|"
    r"epilogue_restores__|tablejump\w*)"
)


def start_profile(lib, h, elf: Path, worst_cap: int) -> FunctionMap:
    """Start counting in the harness `h`, by the functions of `elf`; returns their map.
    worst_cap: how many of the longest steps keep their own counts."""
    fmap = function_map(elf)
    words = (ctypes.c_uint16 * len(fmap.func_of_word))(*fmap.func_of_word)
    entry = (ctypes.c_uint8 * len(fmap.entry_words))(*fmap.entry_words)
    if lib.unocore_profile_start(h, words, len(words), entry, len(fmap.names), worst_cap) != 0:
        raise UnoSetupError(f"cannot start the profile ({len(fmap.names)} functions)")
    return fmap


def _profile_arrays(lib, h):
    """(info, {kind: (self, calls, inclusive, edge calls, edge inclusive)}, worst steps): the
    first three by (context, function), the edges by (caller, callee), all as floats."""
    import numpy as np

    info = _ProfInfo()
    lib.unocore_profile_info(h, ctypes.byref(info))
    nkeys, nfn, nf = info.nkeys, info.nctx * info.nfuncs, info.nfuncs
    kinds = {}
    for k, name in enumerate(PROF_KINDS):
        bufs = [(ctypes.c_uint64 * nkeys)() for _ in range(3)]
        if lib.unocore_profile_read(h, k, *bufs, nkeys) != nkeys:
            raise RuntimeError("unocore_profile_read failed")
        cyc, cal, inc = (np.frombuffer(b, dtype=np.uint64).astype(np.float64) for b in bufs)
        edges = (
            (cal[nfn:].reshape(nf, nf), inc[nfn:].reshape(nf, nf))
            if info.nedges
            else (np.zeros((nf, nf)), np.zeros((nf, nf)))
        )
        kinds[name] = (
            cyc[:nfn].reshape(info.nctx, nf),
            cal[:nfn].reshape(info.nctx, nf),
            inc[:nfn].reshape(info.nctx, nf),
            *edges,
        )
    worst = []
    hdr = _ProfStep()
    entries = (_ProfEntry * nkeys)()
    for i in range(info.worst_kept):
        n = lib.unocore_profile_worst(h, i, ctypes.byref(hdr), entries, nkeys)
        worst.append(
            (
                hdr.fall - hdr.rise,
                hdr.rise,
                hdr.desc if hdr.has_desc else None,
                [(e.key, e.cycles, e.calls, e.incl) for e in entries[:n]],
            )
        )
    return info, kinds, worst


def read_profile(lib, h, fmap: FunctionMap) -> dict:
    """uno_timing["profile"]: where the steps' cycles go (see unocore.c, "Profile").

    For each kind of step (all, fix, sonar, replanning, radio_rx, no_flags: by the GPIOR0
    descriptor; worst_1pct: the longest 1 % of all steps; worst_step: the longest one):
    - `steps`, `mean_step_us`; `counted_share` (cycles counted / cycles between PB0's edges:
      1.0 when nothing is missed) and `named_share` (the share of those inside a named function);
    - `functions`: the top 15 of the main line by self cycles (at PCs inside the function),
      with their share of the step time, microseconds per step, calls per step (arrivals at an
      entry point from another function) and inclusive microseconds per step (CALL to RET,
      interrupts left out);
    - `inclusive`: the top 15 by inclusive time; `calls`: the top 15 caller -> callee edges
      of the firmware's own functions by inclusive time (library-internal calls left out);
    - `interrupts`: each handler with everything it ran, apart from the main line;
    - `float_library`, `integer_library` (avr-libc, libgcc): together, one by one, and the
      firmware functions that call into them.
    Shares are of the step time of that kind of step; microseconds are per step of it."""
    info, kinds, worst = _profile_arrays(lib, h)
    out: dict = {
        "method": "per instruction (exact, not sampled): while PB0 is high, each instruction's cycles go to "
        "the function whose ELF symbol holds its PC (self); an interrupt's cycles (its entry, its "
        "handler and what that calls) to the interrupt; inclusive times from a shadow call stack "
        "(CALL to RET, interrupts left out)",
        "symbols": len(fmap.names) - 1,
        "instructions_counted": info.instructions,
        "kinds": {},
    }
    for k, name in enumerate(PROF_KINDS):
        out["kinds"][name] = _profile_kind(fmap, kinds[name], info.steps[k], info.step_cycles[k], info.attributed[k])
    # the worst 1 % of all steps, and the single worst, from the longest steps the harness kept
    n_all = info.steps[0]
    n_worst = max(1, math.ceil(n_all / 100)) if n_all else 0
    ranked = sorted(worst, key=lambda w: (-w[0], w[1]))
    out["kinds"]["worst_1pct"] = _profile_chosen(fmap, info, ranked[:n_worst], n_worst)
    out["kinds"]["worst_step"] = _profile_chosen(fmap, info, ranked[:1], 1 if n_all else 0)
    # the shadow call stack's health: frames open when a step ended (main's code raises
    # and lowers PB0, so 0 when every call met its return), calls too deep to follow
    out["open_frames_at_step_end"] = info.open_frames
    if info.depth_lost:
        out["calls_too_deep"] = info.depth_lost
    return out


def _profile_chosen(fmap: FunctionMap, info, chosen: list, wanted: int) -> dict:
    """_profile_kind over some of the longest steps the harness kept (their own counts)."""
    import numpy as np

    nf, nfn = info.nfuncs, info.nctx * info.nfuncs
    cyc, cal, inc = (np.zeros((info.nctx, nf)) for _ in range(3))
    ecal, einc = np.zeros((nf, nf)), np.zeros((nf, nf))
    for _dur, _rise, _desc, entries in chosen:
        for key, c, n, i in entries:
            if key >= nfn:
                caller, callee = divmod(key - nfn, nf)
                ecal[caller, callee] += n
                einc[caller, callee] += i
                continue
            ctx, f = divmod(key, nf)
            cyc[ctx, f] += c
            cal[ctx, f] += n
            inc[ctx, f] += i
    w = _profile_kind(fmap, (cyc, cal, inc, ecal, einc), len(chosen), sum(c[0] for c in chosen), float(cyc.sum()))
    if chosen:
        w["threshold_us"] = round(chosen[-1][0] * 1e6 / CLOCK_HZ, 1)
        w["flags"] = {
            flag: sum(1 for c in chosen if c[2] is not None and c[2] & bit) for flag, bit in DESC_FLAGS.items()
        }
    if len(chosen) < wanted:
        w["note"] = f"only the {len(chosen)} longest steps were kept (worst_cap)"
    return w


def _profile_kind(fmap: FunctionMap, arrays, steps: int, step_cycles: int, attributed: float) -> dict:
    import numpy as np

    cyc, cal, inc, ecal, einc = arrays
    if not steps:
        return {"steps": 0}
    us = 1e6 / CLOCK_HZ
    nosym = fmap.no_symbol

    frames_of = ecal.sum(axis=0)  # main-line frames opened for each function (CALLs, tail calls)

    def row(
        name: str, cycles: float, calls: float | None = None, incl: float | None = None, frames: float | None = None
    ) -> dict:
        r = {
            "function": short_name(name),
            "symbol": name,
            "cycles": int(cycles),
            "share": round(float(cycles) / step_cycles, 4),
            "us_per_step": round(float(cycles) * us / steps, 1),
        }
        if calls is not None:
            r["calls_per_step"] = round(float(calls) / steps, 2)
        if incl is not None and incl > 0:
            r["inclusive_us_per_step"] = round(float(incl) * us / steps, 1)
            r["inclusive_share"] = round(float(incl) / step_cycles, 4)
            if frames is not None and frames > 0:  # per frame: per CALL (or tail call) to it
                r["inclusive_us_per_call"] = round(float(incl) * us / float(frames), 1)
        return r

    main_self, main_calls, main_incl = cyc[0], cal[0], inc[0]
    top_self = [int(f) for f in main_self.argsort()[::-1][:15] if main_self[f] > 0]
    top_incl = [int(f) for f in main_incl.argsort()[::-1][:15] if main_incl[f] > 0]
    interrupts = []
    for ctx in range(1, cyc.shape[0]):
        total = float(cyc[ctx].sum())
        if total <= 0:
            continue
        handler = fmap.vector_handlers.get(ctx, f"__vector_{ctx}")
        entries = sum(cal[ctx, f] for f, n in enumerate(fmap.names) if n == handler) if handler else 0
        inside = [int(f) for f in cyc[ctx].argsort()[::-1][:5] if cyc[ctx, f] > 0]
        interrupts.append(
            {
                "vector": ctx,
                "source": VECTORS_328P[ctx] if ctx < len(VECTORS_328P) else None,
                "handler": handler,
                "cycles": int(total),
                "share": round(total / step_cycles, 4),
                "us_per_step": round(total * us / steps, 1),
                "entries_per_step": round(float(entries) / steps, 2),
                "functions": [{"function": short_name(fmap.names[f]), "cycles": int(cyc[ctx, f])} for f in inside],
            }
        )
    interrupts.sort(key=lambda r: -r["cycles"])

    float_fs = [f for f, raw in enumerate(fmap.raw_names) if FLOAT_LIBRARY.match(raw)]
    int_fs = [f for f, raw in enumerate(fmap.raw_names) if INTEGER_LIBRARY.match(raw)]
    library_fs = set(float_fs) | set(int_fs)
    firmware_fs = [f for f in range(len(fmap.names)) if f not in library_fs]

    def edge(caller: int, callee_name: str, calls: float, incl: float) -> dict:
        return {
            "caller": short_name(fmap.names[caller]),
            "callee": callee_name,
            "calls_per_step": round(calls / steps, 2),
            "inclusive_us_per_step": round(incl * us / steps, 1),
            "inclusive_share": round(incl / step_cycles, 4),
        }

    def library(fs: list[int]) -> dict:
        per = sorted(((float(cyc[:, f].sum()), float(cal[:, f].sum()), f) for f in fs), reverse=True)
        total = sum(c for c, _, _ in per)
        # who calls into the library: the firmware's functions (main line), inclusive time
        into = einc[np.ix_(firmware_fs, fs)].sum(axis=1)
        n_into = ecal[np.ix_(firmware_fs, fs)].sum(axis=1)
        callers = [
            edge(firmware_fs[i], "(library)", float(n_into[i]), float(into[i]))
            for i in into.argsort()[::-1][:10]
            if into[i] > 0
        ]
        return {
            "cycles": int(total),
            "share": round(total / step_cycles, 4),
            "us_per_step": round(total * us / steps, 1),
            "functions": [row(fmap.names[f], c, n, inc[0, f], frames_of[f]) for c, n, f in per if c > 0],
            "callers": callers,
        }

    # the firmware's calls (library-internal ones left out), by inclusive time
    fw_einc = einc[firmware_fs, :]
    order = np.dstack(np.unravel_index(fw_einc.ravel().argsort()[::-1][:15], fw_einc.shape))[0]
    call_edges = [
        edge(firmware_fs[i], short_name(fmap.names[j]), float(ecal[firmware_fs[i], j]), float(einc[firmware_fs[i], j]))
        for i, j in order
        if fw_einc[i, j] > 0
    ]

    return {
        "steps": int(steps),
        "mean_step_us": round(step_cycles * us / steps, 1),
        "counted_share": round(attributed / step_cycles, 4),
        "named_share": round(1 - float(cyc[:, nosym].sum()) / attributed, 4) if attributed else None,
        "interrupt_share": round(sum(r["cycles"] for r in interrupts) / step_cycles, 4),
        "functions": [row(fmap.names[f], main_self[f], main_calls[f], main_incl[f], frames_of[f]) for f in top_self],
        "inclusive": [
            {
                "function": short_name(fmap.names[f]),
                "symbol": fmap.names[f],
                "inclusive_share": round(float(main_incl[f]) / step_cycles, 4),
                "inclusive_us_per_step": round(float(main_incl[f]) * us / steps, 1),
                "calls_per_step": round(float(main_calls[f]) / steps, 2),
            }
            for f in top_incl
        ],
        "calls": call_edges,
        "interrupts": interrupts,
        "float_library": library(float_fs),
        "integer_library": library(int_fs),
    }
