"""The simulated camera on a core of its own: frames drawn and located in a second process.

A frame's journey in the simulator is: render it from the true pose (rovernav.sim.camera), keep
it in the run log now and then, and after the camera's latency (60 ms, six of the rover's steps)
hand it to the host's vision code (rovernav.vision.Locator). Rendering and locating are the larger
part of a simulated mission's work and depend on nothing the loop does in between: the pose and
the noise are fixed when the frame is taken, and the locator's state is its own. So they can run
beside the loop rather than in it: `CameraProcess` sends each frame's scene and noise draw to a
worker process, which renders and locates it while the loop steps on, and takes the detection
back when its latency has passed.

Nothing changes but where the work is done. The loop draws the frame's noise offsets from the
simulation's generator at the moment it would have drawn them (`Renderer.noise_offsets`), the
worker draws with `Renderer.render_at` and locates with a `Locator` made from the same
configuration, frames are taken back in the order they were sent, and a frame the log keeps is
encoded in the worker and comes back with its detection (the log takes a kept frame as the host
does, after the latency, stamped with the time it was taken, in both ways of running).
tests/test_camera_process.py checks that a mission's samples, events, report and log channels
are identical with and without it.

It pays on a machine with a core to spare: `rovernav sim` uses it when it writes no video
(`--camera-process auto`); trials, whose workers fill every core already, do not.
"""

from __future__ import annotations

import atexit
import os
import socket
import subprocess
import sys
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any


class CameraProcessError(RuntimeError):
    """The camera process stopped or failed (its error is in the message). Not a RovernavError:
    nothing the user gave is wrong, so the command line reports it as an internal error (exit 3)."""


def _serve(conn) -> None:
    """The worker: set up by ("camera", renderer_args, locator_args), told the arena by ("scene",
    Scene), then renders and locates frames until told to stop (None) or the socket closes. An
    error is said once; the worker then waits for the next camera. Ctrl-C is the parent's to
    handle (it closes the socket, and the worker ends)."""
    import dataclasses
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    from ..runlog.images import encode_jpeg
    from ..vision import Locator
    from .camera import Renderer

    renderer = locator = base = None
    failed = False
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        if job is None:
            return
        try:
            if job[0] == "camera":
                renderer, locator, base, failed = Renderer(*job[1]), Locator(*job[2]), None, False
            elif job[0] == "scene":
                base = job[1]
            elif not failed:
                taken_s, rover, hidden, offsets, keep_image = job
                frame = renderer.render_at(dataclasses.replace(base, rover=rover, hidden=hidden), offsets)
                jpeg = encode_jpeg(frame) if keep_image else None
                conn.send(("frame", (locator.locate(frame, taken_s), jpeg)))
        except Exception as exc:  # noqa: BLE001 - said to the parent, which raises it there
            failed = True
            conn.send(("error", f"{type(exc).__name__}: {exc}"))


# How long the loop waits for a frame's answer before it calls the camera process stuck: a frame
# takes under a millisecond, a new arena's floor some tens of milliseconds.
ANSWER_TIMEOUT_S = 60.0


class CameraProcess:
    """Renders and locates frames in a worker process (see the module's doc).

    configure(renderer_args, locator_args): a new camera (a Renderer's and a Locator's arguments)
    submit(taken_s, base, rover, hidden, offsets, keep_image)
    take() -> (Detection, JPEG bytes when keep_image else None) of the oldest frame not yet taken
    drain(): forget the frames not taken (a run that ended)
    close()
    Every failure of the process (it died, it failed, it did not answer) is a CameraProcessError.
    """

    def __init__(self, renderer_args: tuple | None = None, locator_args: tuple | None = None):
        # A plain child interpreter on one end of a socket pair (not multiprocessing's spawn, which
        # imports the caller's __main__ again, nor a fork of a process with OpenCV's, numba's and
        # the log's threads), running this module; it imports the same rovernav as this process.
        # Its start (imports, the arena's floor) overlaps the simulation's own.
        ours, theirs = socket.socketpair()
        package_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "rovernav.sim.camera_process", str(theirs.fileno())],
                pass_fds=(theirs.fileno(),),
                env=env,
                stdin=subprocess.DEVNULL,
            )
        except BaseException:
            ours.close()
            raise
        finally:
            theirs.close()
        self._conn = Connection(ours.detach())
        self._outstanding = 0
        self._base = None
        self._failed = False
        self.in_use = False  # a simulation holds it (see `acquire`)
        if renderer_args is not None and locator_args is not None:
            self.configure(renderer_args, locator_args)

    def _stopped(self, exc: BaseException | None = None) -> CameraProcessError:
        try:
            code = self._proc.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            code = None
        what = f"exit code {code}" if code is not None else "still running, but its socket failed"
        err = CameraProcessError(f"the camera process stopped ({what})")
        err.__cause__ = exc
        return err

    def _send(self, message) -> None:
        try:
            self._conn.send(message)
        except (OSError, ValueError) as exc:  # a closed socket: the process died
            raise self._stopped(exc) from exc

    def configure(self, renderer_args: tuple, locator_args: tuple) -> None:
        self.drain()
        self._send(("camera", renderer_args, locator_args))
        self._base = None
        self._failed = False

    def alive(self) -> bool:
        return self._proc.poll() is None and not self._conn.closed

    def drain(self) -> None:
        if self._failed:  # it said why, and sends nothing more for this camera
            self._outstanding = 0
        while self._outstanding > 0:
            self.take()

    def _recv(self) -> tuple[str, Any]:
        try:
            if not self._conn.poll(ANSWER_TIMEOUT_S):
                raise CameraProcessError(f"the camera process did not answer in {ANSWER_TIMEOUT_S:g} s")
            kind, what = self._conn.recv()
        except (EOFError, OSError) as exc:
            raise self._stopped(exc) from exc
        if kind == "error":
            self._failed = True
            raise CameraProcessError(f"the camera process failed: {what}")
        return kind, what

    def submit(self, taken_s: float, base, rover, hidden, offsets, keep_image: bool) -> None:
        """A frame taken at taken_s of the scene `base` with the rover at `rover` (x_m, y_m,
        heading_deg) and its `hidden` markers, noise `offsets` (Renderer.noise_offsets); its JPEG
        too when keep_image."""
        if base is not self._base:  # the arena, sent when it is a new one: a frame then costs a pose
            self._send(("scene", base))
            self._base = base
        self._send((taken_s, rover, hidden, offsets, keep_image))
        self._outstanding += 1

    def take(self):
        """(the Detection, the JPEG or None) of the oldest frame submitted and not yet taken."""
        if self._outstanding <= 0:
            raise CameraProcessError("no frame is waiting to be located")
        kind, what = self._recv()
        if kind != "frame":
            raise CameraProcessError(f"the camera process sent {kind!r} where a frame was due")
        self._outstanding -= 1
        return what

    def close(self) -> None:
        """Stop the process (at once if it does not stop when asked) and close the socket."""
        try:
            self._conn.send(None)
        except (OSError, ValueError):
            pass
        try:
            self._proc.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait(timeout=2.0)
        self._conn.close()
        self.in_use = False


_shared: CameraProcess | None = None


def acquire(renderer_args: tuple, locator_args: tuple) -> CameraProcess:
    """A camera process set up for a new camera, for one simulation until `release`: this
    process's shared one, started on first use and kept for the next simulation (one after
    another in a process, as trials' workers and the benchmarks run them, each then pays no
    start-up; closed when the process exits), or a process of its own when a simulation holds the
    shared one already."""
    global _shared
    if _shared is not None and _shared.in_use:
        proc = CameraProcess(renderer_args, locator_args)
    else:
        if _shared is None or not _shared.alive():
            _shared = CameraProcess()
            atexit.register(_shared.close)
        proc = _shared
        proc.configure(renderer_args, locator_args)
    proc.in_use = True
    return proc


def release(proc: CameraProcess, ended_well: bool) -> None:
    """The simulation is done with `proc`. After a run that ended well, the frames still in flight
    are forgotten and the shared process waits for the next simulation; after one that did not
    (an error, Ctrl-C: a message may be half read), the process is closed."""
    if ended_well and proc is _shared:
        try:
            proc.drain()
            proc.in_use = False
            return
        except CameraProcessError:
            pass
    proc.close()


def spare_core() -> bool:
    """Whether this process has a core to spare for a camera process: two usable cores or more."""
    try:
        usable = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = os.cpu_count() or 1
    return usable >= 2


if __name__ == "__main__":  # the camera process: python -m rovernav.sim.camera_process FD
    _serve(Connection(int(sys.argv[1])))
