"""Fixtures the tests share: what several test files set up alike.

repo_root          the checkout's root folder (scenarios/, benchmarks/, docs/, ...)
scenario_toml      a shared scenario's TOML text, by name ("seed-fig4-8-unknown-obstacle")
fig48              that scenario, loaded (the one most tests run)
rovernav_command   `python -m rovernav.cli ARGS` in a subprocess, as a user types it
benchmark_module   a script of benchmarks/ imported as a module, to call its functions
native_core        the firmware core's library built (once), and its RoverCore class
simulate           a Simulation of a scenario with its progress lines silenced
uno_built          the Uno image and its simavr harness built (once); skips without the AVR tools
"""

from __future__ import annotations

import importlib.util
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
FIG48 = "seed-fig4-8-unknown-obstacle"


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture(scope="session")
def scenario_toml():
    """name -> the text of scenarios/NAME.toml."""

    def text(name: str) -> str:
        return (REPO_ROOT / "scenarios" / f"{name}.toml").read_text()

    return text


@pytest.fixture(scope="session")
def fig48():
    """Figure 4.8's arena with its unknown obstacle (a frozen Scenario: safe to share)."""
    from rovernav.scenario import load_scenario

    return load_scenario(FIG48)


@pytest.fixture(scope="session")
def rovernav_command():
    """run(*args, cwd=None, timeout_s=60, memory_limit_bytes=None) -> subprocess.CompletedProcess:
    `python -m rovernav.cli ARGS` with this checkout's host/ on PYTHONPATH (text output captured;
    with memory_limit_bytes, the process's address space capped: no unbounded work)."""
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT / "host")}

    def run(*args, cwd=None, timeout_s: float = 60.0, memory_limit_bytes: int | None = None):
        def limit() -> None:
            resource.setrlimit(resource.RLIMIT_AS, (memory_limit_bytes, memory_limit_bytes))

        return subprocess.run(
            [sys.executable, "-m", "rovernav.cli", *map(str, args)],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            env=env,
            cwd=cwd,
            preexec_fn=limit if memory_limit_bytes is not None else None,
        )

    return run


@pytest.fixture(scope="session")
def benchmark_module():
    """name -> benchmarks/NAME.py imported as a module (benchmarks/ is not a package); each once."""
    loaded = {}

    def load(name: str):
        if name not in loaded:
            spec = importlib.util.spec_from_file_location(f"benchmarks_{name}", REPO_ROOT / "benchmarks" / f"{name}.py")
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            loaded[name] = module
        return loaded[name]

    return load


@pytest.fixture(scope="session")
def native_core():
    """The native core class (rovernav.cores.NativeCore), its library built first (once a session; build_library is a no-op when
    the library is newer than every source)."""
    from rovernav.cores.native import NativeCore, build_library

    build_library()
    return NativeCore


@pytest.fixture(scope="session")
def simulate():
    """(scenario, **SimOptions fields) -> a Simulation, not yet run, that prints nothing."""
    from rovernav.sim.runner import SimOptions, Simulation

    def make(scenario, **options):
        return Simulation(scenario, SimOptions(**options), progress=lambda t_s, text: None)

    return make


@pytest.fixture(scope="module")
def built():
    """(the simavr UART bridge, the Uno image's ELF), both built (test_avrsim.build_bridge_and_image);
    the test is skipped when the AVR tools are missing."""
    from test_avrsim import build_bridge_and_image

    return build_bridge_and_image()


@pytest.fixture(scope="session")
def uno_built():
    """The Uno image and its simavr harness (rovernav.cores.uno_harness.ensure_built), built once a
    session; the test is skipped, saying what to install, when the AVR toolchain or libsimavr-dev
    is missing. The test_uno_*.py files take it as their `built`."""
    from rovernav.cores import uno_harness as harness

    missing = harness.missing_packages()
    if missing:
        pytest.skip("the Uno simulation needs Debian packages: " + ", ".join(sorted(missing)))
    try:
        return harness.ensure_built()
    except harness.UnoSetupError as exc:
        if "apt-get install" in str(exc) or "toolchain" in str(exc):
            pytest.skip(str(exc))
        raise
