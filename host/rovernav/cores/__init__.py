"""The rover's firmware as the simulator and the tests step it: one protocol, two implementations.

    protocol.py      RoverCore (step / probe / auth_counters / close), StepOut, Probe, FirmwareBuildError
    native.py        NativeCore: the core compiled for this machine, through its C ABI (ctypes)
    uno.py           UnoCore: the Uno image itself in simavr (`rovernav sim --rover uno`)
    uno_harness.py   the simavr harness (tools/avrsim/unocore.c) and the image: building, loading
    elf.py           the image's ELF: section headers, symbol table (which function holds a PC)
    profile.py       where the image's steps spend their cycles, by function

`rovernav.cores.uno` is imported only when the Uno is asked for.
"""

from .native import NativeCore
from .protocol import FirmwareBuildError, Probe, RoverCore, StepOut

__all__ = ["FirmwareBuildError", "NativeCore", "Probe", "RoverCore", "StepOut"]
