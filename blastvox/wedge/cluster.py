"""Running a wedge's shots on Dask: a LocalCluster by default, or an existing scheduler.

Each shot is one task (:func:`blastvox.wedge.shot.run_shot`) on a worker with one
thread, so a worker runs one shot at a time; the simulator's compiled kernels are
shared through their on-disk cache. Shots that finished in an earlier wedge are not
submitted. A shot that fails, or whose worker dies, is reported as failed and the
others go on. On Ctrl-C the client and a local cluster are closed (stopping its
workers); every stage file is written atomically, so the next run resumes.

An existing cluster (``--scheduler tcp://host:8786``, e.g. one started by
dask-jobqueue on a farm or the Dask Kubernetes operator) needs blastvox installed
on its workers at the same version and the scene, its inputs and the wedge's
output directory on a file system they all share, at the same paths.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any

from blastvox.errors import WedgeError
from blastvox.wedge.plan import ShotSpec
from blastvox.wedge.shot import cached_result, record, run_shot

#: Seconds to wait for an existing scheduler before giving up.
CONNECT_TIMEOUT_S = 10.0


@contextlib.contextmanager
def connect(scheduler: str | None, workers: int,
            timeout_s: float = CONNECT_TIMEOUT_S) -> Iterator[Any]:
    """A ``dask.distributed.Client``: to ``scheduler`` if given, else to a new
    LocalCluster of ``workers`` single-threaded worker processes (see
    :func:`local_workers`). An unreachable scheduler is one
    :class:`~blastvox.errors.WedgeError` line."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        with client_of(scheduler, timeout_s) as client:
            yield client
        return
    with _workers_ignore_ctrl_c():
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
    with cluster, Client(cluster) as client:
        yield client


def client_of(scheduler: str, timeout_s: float) -> Any:
    """A client of the existing ``scheduler``, connected within ``timeout_s`` or one
    WedgeError line naming the address and the cause (:mod:`blastvox.wedge.probe` asks
    first; Dask's own connection is bounded by a watchdog, since it can wait past its
    timeout)."""
    from dask.distributed import Client

    from blastvox.wedge.probe import probe

    left = probe(scheduler, timeout_s)
    made: dict[str, Any] = {}

    def make() -> None:
        try:
            made["client"] = Client(scheduler, timeout=f"{left}s")
        except BaseException as exc:  # handed to the caller's thread
            made["error"] = exc

    thread = threading.Thread(target=make, name="blastvox-connect", daemon=True)
    thread.start()
    thread.join(left + 2.0)
    if thread.is_alive():
        raise WedgeError(f"--scheduler {scheduler}: the scheduler accepted the connection "
                         f"but did not finish Dask's handshake within {timeout_s:g} s "
                         "(--connect-timeout)")
    exc = made.get("error")
    if isinstance(exc, MemoryError):
        raise WedgeError(f"--scheduler {scheduler}: it answers, but not in Dask's protocol "
                         "(its reply read as a frame larger than memory); not a Dask "
                         "scheduler") from None
    if exc is not None:
        if not isinstance(exc, Exception):
            raise exc
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise WedgeError(f"--scheduler {scheduler}: cannot connect to the Dask scheduler "
                         f"({reason})") from None
    return made["client"]


def local_workers(asked: int | None, shots: int) -> int:
    """Workers of a local cluster: as asked, else one per CPU; never more than shots."""
    return max(1, min(asked or os.cpu_count() or 1, shots))


@contextlib.contextmanager
def _workers_ignore_ctrl_c() -> Iterator[None]:
    """Ignore SIGINT while the local cluster starts its processes: they inherit the
    ignored signal, so a Ctrl-C, which a terminal sends to the whole process group,
    stops only the wedge, which then closes the cluster and its workers (instead of
    each worker printing its own KeyboardInterrupt traceback). A Ctrl-C in the second
    this takes is lost; SIGTERM still stops everything."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def dashboard_link(client: Any, remote: bool) -> str | None:
    """The address of the scheduler's dashboard, if it serves one (a local one draws its
    plots only with bokeh installed)."""
    if not remote and importlib.util.find_spec("bokeh") is None:
        return None
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # an old or unusual scheduler: no link is no harm
        return None
    return client.dashboard_link if "dashboard" in services else None


def run_shots(client: Any, shots: list[ShotSpec],
              done: Callable[[dict[str, Any]], None] = lambda result: None
              ) -> list[dict[str, Any]]:
    """Results of ``shots`` in their order: finished ones read back ("cached"), the rest
    run on ``client``'s workers; ``done`` is called with each result as it arrives."""
    from dask.distributed import as_completed

    results: dict[int, dict[str, Any]] = {}
    todo = []
    for spec in shots:
        cached = cached_result(spec)
        if cached is None:
            todo.append(spec)
        else:
            results[spec.index] = cached
            done(cached)
    futures = {client.submit(run_shot, spec, pure=False): spec for spec in todo}
    for future in as_completed(futures):
        spec = futures[future]
        try:
            result = future.result()
        except Exception as exc:  # its workers died (out of memory, killed): one shot lost
            what = "worker lost" if type(exc).__name__ == "KilledWorker" else "task failed"
            reason = str(exc).split("\n")[0]
            result = record(spec, "failed", f"{what}: {type(exc).__name__}: {reason}",
                            {}, {}, 0.0)
        results[spec.index] = result
        done(result)
    return [results[spec.index] for spec in shots]
