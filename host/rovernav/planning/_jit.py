"""The compiler for the planner's inner loops: numba when it is installed, plain Python if not.

The search kernels (`astar`, `segment`, `simplify`) are written in the subset of Python that
numba compiles, and stay valid plain Python, so each has a `.py_func` either way (the tests
compare the compiled and the plain versions). Compiled code is cached on disk beside the
sources, so only the first run on a machine pays the compile time (about a second).
"""

from __future__ import annotations

import logging

log = logging.getLogger("rovernav.planning")

try:
    import numba as _numba
except ImportError:  # pragma: no cover - numba is a dependency; this keeps a bare install working
    _numba = None

COMPILED = _numba is not None
if not COMPILED:  # pragma: no cover
    log.warning("numba is not installed: the planner runs its search in plain Python (30-50 times slower)")


def njit(func):
    """Compile `func` with numba (nopython, cached) or return it unchanged, with `.py_func` set."""
    if COMPILED:
        return _numba.njit(cache=True, nogil=True)(func)
    func.py_func = func  # pragma: no cover
    return func  # pragma: no cover
