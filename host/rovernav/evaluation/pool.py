"""Running the jobs: `rovernav trials`' in this process, or on a dask.distributed cluster with hung
runs cancelled (run_jobs); the benchmarks' (benchmarks/*.py) in a pool of local processes (map_runs)."""

from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import logging
import time
import traceback
import uuid
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from ..files import write_atomic
from .jobs import TrialJob, TrialsError, failure_row, run_trial

log = logging.getLogger("rovernav.evaluation.trials")

HANG_GRACE_S = 60.0  # past --run-timeout, how long a run may take to stop itself before it is killed
POLL_S = 2.0  # how often the dask loop looks for hung runs while none completes


# ---------------------------------------------------------------- running the jobs


def run_jobs(
    jobs: list[TrialJob],
    workers: int,
    scheduler: str | None = None,
    on_start: Callable[[], None] | None = None,
    on_result: Callable[[int, int, dict], None] | None = None,
    trial: Callable[..., dict] = run_trial,
    hang_grace_s: float = HANG_GRACE_S,
) -> list[dict]:
    """Run every job and return one row per job, in completion order.

    workers = 0 and no scheduler: in this process, one after another. Otherwise on a dask
    cluster: a local one of `workers` processes (one thread each) or the one at `scheduler`.
    `on_start()` is called once the cluster is up, `on_result(done, total, row)` as each run
    ends. `trial` is called with a job's `args` (run_trial; tests pass a stand-in). A run that
    raises gives an "error" row; on a cluster, one still running `hang_grace_s` past its
    run_timeout_s gives a "hung" row. Raises TrialsError when the scheduler cannot be reached.
    """
    notify = on_result or (lambda done, total, row: None)
    if scheduler is None and workers == 0:
        if on_start:
            on_start()
        rows = []
        for job in jobs:
            rows.append(_call(trial, job))
            notify(len(rows), len(jobs), rows[-1])
        return rows
    with _dask_client(workers, scheduler) as client:
        if on_start:
            on_start()
        return _run_on_client(client, jobs, trial, hang_grace_s, notify)


def _call(trial: Callable[..., dict], job: TrialJob) -> dict:
    try:
        return trial(*job.args)
    except Exception as exc:  # a run that raises is a result to record, not the end of the benchmark
        return _error_row(job, exc)


def _error_row(job: TrialJob, exc: BaseException) -> dict:
    text = "".join(traceback.format_exception(exc))
    log.debug("%s raised:\n%s", job.label, text)
    with contextlib.suppress(OSError):
        job.run_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(job.run_dir / "error.txt", text)
    return failure_row(job, "error", f"{type(exc).__name__}: {exc}".splitlines()[0])


@contextlib.contextmanager
def _dask_client(workers: int, scheduler: str | None):
    """A client of the cluster at `scheduler`, or of a new local one. Dask's own logging is kept
    to errors here and silenced in local workers (a run's failure is in its row and error.txt)."""
    from distributed import Client, LocalCluster

    dask_log = logging.getLogger("distributed")
    level = dask_log.level
    dask_log.setLevel(logging.ERROR)
    try:
        if scheduler is not None:
            try:
                client = Client(scheduler)
            except (OSError, ValueError, TypeError) as exc:  # refused, timed out, or not an address
                raise TrialsError(f"cannot use the dask scheduler at {scheduler!r}: {exc}") from None
            with client:
                yield client
        else:
            with (
                LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.CRITICAL,
                ) as cluster,
                Client(cluster) as client,
            ):
                yield client
    finally:
        dask_log.setLevel(level)


def _run_on_client(
    client,
    jobs: list[TrialJob],
    trial: Callable[..., dict],
    hang_grace_s: float,
    notify: Callable[[int, int, dict], None],
) -> list[dict]:
    """Keep no more jobs in flight than the cluster has threads, so that a job starts when it is
    submitted and its wall time can be watched from here."""
    from distributed import wait

    queue = collections.deque(jobs)
    in_flight: dict = {}  # future -> (job, monotonic time submitted)
    rows: list[dict] = []

    def done(row: dict) -> None:
        rows.append(row)
        notify(len(rows), len(jobs), row)

    while queue or in_flight:
        free = max(1, sum(client.nthreads().values())) - len(in_flight)
        for _ in range(min(free, len(queue))):
            job = queue.popleft()
            key = f"trial-{job.strategy}-{job.arena}-s{job.seed}-{uuid.uuid4().hex[:8]}"
            future = client.submit(trial, *job.args, key=key)
            in_flight[future] = (job, time.monotonic())
        try:
            finished = wait(list(in_flight), timeout=POLL_S, return_when="FIRST_COMPLETED").done
        except TimeoutError:
            finished = set()
        for future in finished:
            job, _ = in_flight.pop(future)
            try:
                row = future.result()
            except Exception as exc:  # the run raised, or its worker died under it
                row = _error_row(job, exc)
            done(row)
        now = time.monotonic()
        for future, (job, submitted) in list(in_flight.items()):
            if job.run_timeout_s is not None and now - submitted > job.run_timeout_s + hang_grace_s:
                del in_flight[future]
                _kill(client, future)
                done(
                    failure_row(
                        job,
                        "hung",
                        f"still running {now - submitted:.0f} s after it started "
                        f"(--run-timeout {job.run_timeout_s:g} s); its worker was restarted",
                    )
                )
    return rows


def _kill(client, future) -> None:
    """Cancel a run that does not stop, and restart its worker (only a worker under a nanny can be)."""
    holders = [w for w, keys in client.processing().items() if future.key in keys]
    future.cancel()
    if holders:
        status = client.restart_workers(holders, raise_for_error=False)
        if any(s != "OK" for s in status.values()):
            log.warning("could not restart the worker of a hung run (%s): it stays busy", status)


# ---------------------------------------------------------------- the benchmarks' runs


def map_runs(
    run: Callable[..., Any], items: Iterable[Any], workers: int, *, ordered: bool = True, star: bool = False
) -> Iterator[tuple[Any, Any]]:
    """Call `run(item)` (`run(*item)` with star) for every item in a pool of `workers` local
    processes, and yield (item, result) pairs: in the items' order (ordered, as Executor.map
    does) or as each run ends. The caller prints its progress as the pairs come.

    Every item is submitted at once. A run that raises raises here when its pair is due; the runs
    not yet started are then cancelled. The pool is shut down, waiting for the runs under way,
    when the iteration ends. `run` must be picklable: a module-level function.
    """
    items = list(items)
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {(pool.submit(run, *item) if star else pool.submit(run, item)): item for item in items}
        try:
            for future in futures if ordered else concurrent.futures.as_completed(futures):
                yield futures[future], future.result()
        except BaseException:
            for future in futures:
                future.cancel()
            raise
