"""``retarget_many``: a corpus to robot motion on a dask.distributed cluster.

The engine is dask.distributed: by default a ``LocalCluster`` of worker processes (one
thread each) on this machine, listening on 127.0.0.1 only, without a dashboard; or the
user's cluster (``scheduler="tcp://HOST:PORT"``, or a ``Client`` of theirs), which is used as
it is: never resized, never shut down. Each input is one task (:func:`~nlo_lab.batch.tasks.retarget_input`);
a video's pose estimation is first split into 30-frame segments, one task each, so a long
video spreads over every worker. Results arrive in any order; each fills its row of
``results.csv`` (:class:`~nlo_lab.batch.table.ResultsTable`). A worker that dies has its
tasks run again elsewhere by the scheduler; the output folders appear whole or not at all.

Inputs and ``out`` must be reachable under the same paths from this process and from every
worker (one machine, or a file system the cluster shares).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import importlib
import logging
import os
import secrets
import shutil
import socket
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

import nlo_lab
from nlo_lab.atomic_files import stale_temp_folders_in
from nlo_lab.batch.inputs import RESULTS_FILE, find_inputs
from nlo_lab.batch.lock import check_out_place, run_lock
from nlo_lab.batch.plan import plan_run
from nlo_lab.batch.progress import Progress
from nlo_lab.batch.settings import BatchSettings
from nlo_lab.batch.table import COLUMNS, ResultsTable, failed_row
from nlo_lab.errors import NloLabError, escape
from nlo_lab.settings import LATENT_ITERATIONS, WORKERS_RANGE, check_int

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["SchedulerError", "CONNECT_TIMEOUT", "available_cores", "retarget_many", "to_frame"]

CONNECT_TIMEOUT = 10.0  # seconds to reach a scheduler
# dask's own bookkeeping, sized for a batch without a dashboard: a LocalCluster of 2 idle workers took 7.6 % of a
# core with dask's defaults (statistical profiling every 10 ms, system monitor every 0.5 s, event-loop ticks every
# 20 ms, memory checks every 0.1 s), 1 % with these. Only our own LocalCluster gets them; a user's cluster keeps its own.
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,  # the profiles feed the dashboard, which we do not start
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.memory.monitor-interval": "1s",  # still ends a runaway worker within a second
}
VIDEO_PRIORITY = 1  # a video's segments start before the single-task inputs: a long one must not end the run alone
WARM_UP_PRIORITY = 10  # each worker loads the model before its first input


class SchedulerError(NloLabError, ConnectionError):
    """No dask scheduler answers at the address given, or the batch extra is missing."""


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def _distributed():
    try:
        return importlib.import_module("distributed")
    except ImportError as err:
        raise SchedulerError(f"nlo-lab batch needs the batch extra: pip install \"nlo_lab[batch]\" ({err})") from None


def _check_scheduler(address: str) -> None:
    """Refuse, within :data:`CONNECT_TIMEOUT`, an address where nothing listens or where something else than a dask
    scheduler does: dask's own client waits forever for the handshake of a server that accepts and stays silent."""
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls"):
        return  # another transport: let dask try
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if not host or not port:
        raise SchedulerError(f"--scheduler {address!r}: expected tcp://HOST:PORT")
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        raise SchedulerError(f"no dask scheduler at {address}: {exc.strerror or exc}") from None
    if parts.scheme != "tcp":
        return  # TLS needs the user's security settings: dask's client handshakes with them
    comm = _distributed().comm

    async def handshake() -> None:
        opened = await asyncio.wait_for(comm.connect(address, timeout=CONNECT_TIMEOUT), CONNECT_TIMEOUT)
        await opened.close()

    with concurrent.futures.ThreadPoolExecutor(1) as pool:  # its own event loop: a notebook's is running already
        try:
            pool.submit(asyncio.run, handshake()).result()
        except Exception as exc:  # noqa: BLE001 - whatever the other end is, it is no dask scheduler
            raise SchedulerError(f"{address} does not answer as a dask scheduler (no handshake within {CONNECT_TIMEOUT:g} s: "
                                 f"{type(exc).__name__}); is it the address `dask scheduler` printed?") from None


@contextlib.contextmanager
def _cluster(client, scheduler: str | None, workers: int | None):
    """The client to run on: the caller's, one connected to ``scheduler``, or one of a new LocalCluster."""
    if client is not None:
        yield client  # the caller's: left as it is
        return
    distributed = _distributed()
    if scheduler:
        _check_scheduler(scheduler)
        try:
            ours = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"no dask scheduler answers at {scheduler}: {exc}") from None
        try:
            yield ours
        finally:
            ours.close()  # our connection only: the cluster and its workers keep running
        return
    environ = dict(os.environ)  # dask's nanny writes its workers' variables into this process's environment
    try:
        try:
            # lazy: the batch extra (dask), like every import of this function
            from nlo_lab.batch.quick_exit import QuickExit

            with importlib.import_module("dask").config.set(LOCAL_CLUSTER_CONFIG):  # read when the servers start
                cluster = distributed.LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                    dashboard_address=None, silence_logs=logging.ERROR,
                    # no dashboard, and the scheduler's HTTP routes (health, metrics) on a free loopback port, not 8787
                    scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                    env={"NLO_LAB_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"},  # torch: one thread per worker
                    plugins={QuickExit()},
                )
        except Exception as exc:  # noqa: BLE001 - most often a script without a __main__ guard
            raise SchedulerError(f"the local dask cluster did not start ({type(exc).__name__}: {exc}); a script that calls "
                                 "retarget_many must do so under `if __name__ == \"__main__\":` (dask's workers import it again)") from None
        try:
            ours = distributed.Client(cluster, set_as_default=False)
            try:
                yield ours
            finally:
                ours.close()
        finally:
            cluster.close()
    finally:
        _restore_environ(environ)


def _restore_environ(environ: dict) -> None:
    """Put this process's environment back as it was (a notebook's later subprocesses must not inherit
    ``OMP_NUM_THREADS=1`` or ``MALLOC_TRIM_THRESHOLD_`` from our cluster)."""
    for key in [k for k in os.environ if k not in environ]:
        del os.environ[key]
    for key, value in environ.items():
        if os.environ.get(key) != value:
            os.environ[key] = value


def _warm_up(client, settings: BatchSettings, token: str) -> list:
    """Every worker builds the retargeter (robot, model) before any input is sent; the first to finish
    decides: a bad setting (an unknown robot ...) or a worker that cannot run nlo_lab is an error here,
    before any row is written. Returns the futures (kept until the run ends, so every worker warms up)."""
    # lazy: the batch extra: only a run on a cluster needs it
    from distributed import as_completed

    from nlo_lab.batch import tasks

    addresses = list(client.scheduler_info().get("workers", {})) or [None]  # none yet: a cluster still growing
    futures = [client.submit(tasks.warm_up, settings, pure=False, priority=WARM_UP_PRIORITY, key=f"nlo-lab-warm-up-{token}-{i}",
                             workers=None if a is None else [a], allow_other_workers=a is None)
               for i, a in enumerate(addresses)]
    first = next(iter(as_completed(futures, loop=client.loop)))
    try:
        version = first.result()
    except Exception as exc:  # noqa: BLE001 - e.g. nlo_lab missing on the workers
        raise SchedulerError(f"the cluster's workers cannot run nlo_lab: {type(exc).__name__}: {' '.join(str(exc).split())}") from None
    if isinstance(version, NloLabError):
        raise version
    if version != nlo_lab.__version__:
        raise SchedulerError(f"the cluster's workers run nlo_lab {version}, this process {nlo_lab.__version__}: install the same version")
    return futures


def _run(client, jobs, table: ResultsTable, progress: Progress, on_row) -> None:
    """Submit every job, collect the rows as they come (a video: plan, segments, then its job).
    The progress starts once a worker has loaded the model (a bad setting is one error line, alone)."""
    # lazy: the batch extra: only a run on a cluster needs it
    from distributed import as_completed

    from nlo_lab.batch import tasks

    token = secrets.token_hex(4)
    warming = _warm_up(client, jobs[0].settings, token)  # noqa: F841 - held until the run ends
    progress.start()
    pending: dict[str, tuple] = {}
    queue = as_completed(loop=client.loop)

    def submit(kind, job, fn, *args, **options):
        future = client.submit(fn, *args, key=f"nlo-lab-{kind}-{token}-{len(pending)}-{job.item.name}", pure=False, **options)
        pending[future.key] = (kind, job)
        queue.add(future)

    for job in _longest_first(jobs):
        if job.item.is_video:
            submit("plan", job, tasks.video_segments, str(job.item.path), priority=VIDEO_PRIORITY)
        else:
            submit("retarget", job, tasks.retarget_input, job)
    try:
        for future in queue:
            kind, job = pending.pop(future.key)
            try:
                value = future.result()
            except Exception as exc:  # noqa: BLE001 - the scheduler gave up on it (a worker died on it again and again)
                value = failed_row(job.item.path, job.item.name, _lost_text(exc, job.item.path),
                                   input_sha256=job.input_sha256, settings=job.fingerprint)
            if kind == "plan" and not isinstance(value, dict):
                if isinstance(value, tasks.Failure):
                    segments = [value]
                else:
                    segments = [client.submit(tasks.video_segment, str(job.item.path), a, b, pure=False, priority=VIDEO_PRIORITY,
                                              key=f"nlo-lab-segment-{token}-{len(pending)}-{a}-{job.item.name}")
                                for a, b in value]
                submit("retarget", job, tasks.retarget_input, job, segments, priority=VIDEO_PRIORITY)
                continue
            future.release()
            table.set(value)
            progress.update(value["status"] == "failed")
            if on_row is not None:
                on_row(value)
    except BaseException:
        client.cancel(list(queue.futures))
        raise


def _longest_first(jobs: list) -> list:
    """The jobs in the order to submit them: videos first (their segments spread over every worker), then the
    other inputs, each kind largest file first. dask starts tasks of equal priority in the order they came, so
    the longest inputs start early and the run does not end on one of them while the other workers wait; the
    file's size stands for its length (frames) without reading it."""

    def size(job) -> int:
        try:
            return job.item.path.stat().st_size
        except OSError:
            return 0  # gone since it was hashed: its task says so

    return sorted(jobs, key=lambda job: (not job.item.is_video, -size(job)))


def _lost_text(exc: BaseException, path) -> str:
    name = type(exc).__name__
    if name == "KilledWorker":
        return escape(f"{path}: the workers running it died again and again (out of memory?); giving up on it")
    if name == "CancelledError":
        return escape(f"{path}: cancelled (the cluster lost the task)")
    return escape(f"{path}: internal error, please report it: {name}: {' '.join(str(exc).split())}")


def _sweep(jobs) -> None:
    """Remove the temporary folders that killed writers left beside the outputs of ``jobs``."""
    for parent in sorted({Path(job.folder).parent for job in jobs}):
        for folder in stale_temp_folders_in(parent):
            shutil.rmtree(folder, ignore_errors=True)


def to_frame(rows: list[dict]):
    """The rows as a pandas DataFrame when pandas is installed, else the list itself."""
    try:
        # lazy: optional (dask's); only this table needs it
        import pandas
    except ImportError:
        return rows

    return pandas.DataFrame(rows, columns=list(COLUMNS))


def retarget_many(inputs, robot: Robot | str, out, client=None, *, init: str = "encoder", iterations: int = LATENT_ITERATIONS, seed: int = 0,
                  weights=None, viewer: bool = False, hand_search=None, hand_slowdown: float = 1.0, workers: int | None = None, scheduler: str | None = None,
                  resume: bool = True, retry_failed: bool = False, progress: bool = False, on_row=None):
    """Retarget every input to ``robot`` on a dask.distributed cluster; the results table.

    Args:
        inputs: files, folders (searched recursively for ``.pose .h5 .npz .mp4 .mov .webm .avi``)
            and manifest ``.txt`` files (one path per line, relative to the manifest's folder).
        robot: a bundled robot's name, a robot spec ``.json``, or a loaded ``Robot``.
        out: the output folder: ``out/<input's path relative to the inputs' common folder,
            without suffix>/`` gets ``trajectory.npz``, ``trajectory.csv``, ``summary.json`` (and
            ``viewer.html`` with ``viewer``); ``out/results.csv`` one row per input.
        client: a ``distributed.Client`` to run on (left open and as it is); default: a new
            ``LocalCluster`` of ``workers`` processes, closed at the end, or ``scheduler``.
        init, iterations, seed, weights: as ``nlo-lab retarget``'s ``--init``, ``--iters``,
            ``--seed``, ``--weights`` (weights: ``"ee=1000,ori=100"``, a mapping or a ``LossWeights``).
        viewer: also write each input's ``viewer.html``.
        hand_search: as ``--hand-search``: fingers the hand stage first searches (``OptimizeSettings.hand_search``;
            None: the robot's default, ``()``: none).
        hand_slowdown: as ``--hand-slowdown``: how much longer than the latent optimisation's the hand stage may make
            each retimed segment (``OptimizeSettings.hand_slowdown``).
        workers: worker processes of the LocalCluster (default: the cores available, at most one per input
            unless there is a video, whose segments spread over every worker).
        scheduler: the address of a running dask scheduler (``tcp://HOST:PORT``).
        resume: skip inputs done before with the same content and settings, and keep the
            ``failed`` rows of inputs that failed on unchanged content (see :mod:`nlo_lab.batch.plan`).
        retry_failed: run inputs that failed before again.
        progress: a progress bar on stderr.
        on_row: called with each row as it is decided (in this process, in the order of arrival).

    Returns:
        The rows of ``results.csv`` in the inputs' order (:data:`nlo_lab.batch.COLUMNS`): a list
        of dicts, or a pandas DataFrame when pandas is installed.

    Raises:
        InputError: an input path that does not exist, no input found, two inputs for one folder.
        SchedulerError: no scheduler at ``scheduler``; the batch extra missing.
        SettingsError: ``workers`` outside :data:`nlo_lab.settings.WORKERS_RANGE`, ``hand_slowdown`` outside
            :data:`nlo_lab.settings.SLOWDOWN_RANGE` (both before any input is read).
        OutputError: ``out`` is empty, not a folder or cannot be written (checked before any input is
            read); another batch is writing it.
        NloLabError: an unknown robot, a bad setting (found when the first worker loads the model, before
            any input runs; no ``results.csv`` is written where there was none).
    """
    if client is not None and scheduler:
        raise SchedulerError("give a client or a scheduler address, not both")
    if workers is not None and (scheduler or client is not None):
        raise SchedulerError("workers sizes the local cluster; with a scheduler or a client, the cluster's own workers run")
    # a Robot is kept as its spec path
    settings = BatchSettings(robot, init, iterations, seed, weights, viewer, hand_search, hand_slowdown)  # type: ignore[arg-type]
    out = check_out_place(out)  # before any input is read
    if workers is not None:
        check_int("workers", workers, *WORKERS_RANGE)
    items = find_inputs(inputs, out)
    with run_lock(out):
        plan = plan_run(items, out, settings, resume=resume, retry_failed=retry_failed)
        table = ResultsTable(out / RESULTS_FILE, [item.name for item in items])
        for row in plan.rows:
            table.set(row)
            if on_row is not None:
                on_row(row)
        bar = Progress(len(plan.jobs), progress, skipped=len(plan.rows))
        try:
            if plan.jobs:
                if workers is None:  # one per core, but not more than there are tasks (a video: one per segment)
                    videos = any(job.item.is_video for job in plan.jobs)
                    workers = available_cores() if videos else min(available_cores(), len(plan.jobs))
                with _cluster(client, scheduler, workers) as ours:
                    _run(ours, plan.jobs, table, bar, on_row)
        finally:
            bar.close()
            table.flush()
            if plan.jobs and client is None and not scheduler:
                _sweep(plan.jobs)  # our workers are gone: what they left half-written goes
    return to_frame(table.ordered())

