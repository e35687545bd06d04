"""Where many runs go: a Dask cluster, and a map of independent tasks over it.

``connect()`` gives a ``dask.distributed.Client``: the one given, one connected to a scheduler's address, or an
embedded ``LocalCluster`` of worker processes with one thread each, listening on localhost only (closed on exit),
whose simulations share the cores: each worker's CPU launches use cores / workers threads (WARP_SIM_CPU_THREADS,
core.cpu_threads), unless that variable is set already.
Nothing else in warp_sim knows which. ``run_tasks`` submits one task per item, each retried by Dask if it raises
or its worker dies (``retries``), and hands back every result as it comes, with a progress bar.

Dask is the ``cluster`` extra (``pip install 'warp-sim[cluster]'``); without it, ``connect`` says so.
"""
from __future__ import annotations

import contextlib
import importlib.util
import os

from .core import cpu_threads
from .util import checks
from .util.progress import tqdm

#: retries of a task whose function raised or whose worker died (Dask reschedules a lost task by itself too)
RETRIES = 2


def require_dask() -> None:
    """ImportError with the install line when Dask is missing (it is imported only where it is used, so that
    ``import warp_sim`` does not pay for it: about half a second)."""
    if importlib.util.find_spec("distributed") is None:
        raise ImportError("sweeps and distributed studies need Dask: pip install 'warp-sim[cluster]' "
                          "(dask[distributed])")


@contextlib.contextmanager
def connect(client=None, scheduler: str | None = None, workers: int | None = None):
    """A dask Client for the block: ``client`` as given; else one connected to ``scheduler`` ("tcp://host:8786");
    else a LocalCluster of ``workers`` processes (default: the number of cores), one thread each, on 127.0.0.1,
    with its dashboard when bokeh is installed. A client or cluster made here is closed at the end."""
    require_dask()
    from distributed import Client, LocalCluster  # optional: the cluster extra

    if client is not None:
        if not isinstance(client, Client):
            raise checks.fail("client", client, "expected a dask.distributed.Client")
        yield client
        return
    if scheduler is not None:
        if not isinstance(scheduler, str) or not scheduler.strip():
            raise checks.fail("scheduler", scheduler, "expected a scheduler address such as 'tcp://host:8786'")
        with Client(scheduler) as connected:
            yield connected
        return
    count = checks.count("workers", (os.cpu_count() or 1) if workers is None else workers)
    # each worker's CPU launches share the cores with the others' (core.cpu_threads), unless the user said
    threads = os.environ.get(cpu_threads.VARIABLE) or str(max(1, cpu_threads.available_cores() // count))
    with LocalCluster(n_workers=count, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=":0", silence_logs=40, env={cpu_threads.VARIABLE: threads}) as cluster, \
            Client(cluster) as local:   # a free port
        yield local


def dashboard(client) -> str | None:
    """The dashboard's link, when one is up (it needs bokeh)."""
    if importlib.util.find_spec("bokeh") is None:
        return None
    try:
        return client.dashboard_link
    except (AttributeError, KeyError):
        return None


def worker_name() -> str:
    """The Dask worker running this task ("local" outside one)."""
    if importlib.util.find_spec("distributed") is None:
        return "local"
    from distributed import get_worker  # optional: the cluster extra

    try:
        worker = get_worker()
    except ValueError:
        return "local"
    return str(worker.name if worker.name is not None else worker.address)


def run_tasks(client, function, tasks: list[tuple[str, tuple]], progress: str | None = None, on_result=None,
              retries: int = RETRIES) -> dict:
    """Run ``function(*args)`` for each (key, args) of ``tasks`` on ``client``'s workers; returns {key: result}.

    Each result is handed to ``on_result(key, result)`` as it arrives (in completion order); ``progress`` is the
    progress bar's label (None: no bar). A task whose function raises is retried ``retries`` times, then its
    exception propagates; a task whose worker dies is run again elsewhere."""
    from distributed import as_completed  # optional: the cluster extra

    futures = {client.submit(function, *args, key=f"warp-sim-{key}", retries=retries, pure=False): key
               for key, args in tasks}
    results = {}
    with tqdm(total=len(futures), unit="task", desc=progress, disable=True if progress is None else None) as bar:
        for future in as_completed(futures):
            key = futures[future]
            results[key] = future.result()
            if on_result is not None:
                on_result(key, results[key])
            bar.update(1)
    return results


def map_tasks(function, tasks: list[tuple[str, tuple]], client=None, scheduler: str | None = None,
              workers: int | None = None, progress: str | None = None, on_result=None) -> list:
    """[function(*args) for each (key, args) of tasks], in order: in this process when no client, scheduler or
    workers is given, else as tasks on that cluster (``connect``, ``run_tasks``); ``on_result(key, result)`` is
    called as each result arrives."""
    if client is None and scheduler is None and workers is None:
        results = {}
        for key, args in tasks:
            results[key] = function(*args)
            if on_result is not None:
                on_result(key, results[key])
    else:
        with connect(client, scheduler, workers) as connected:
            results = run_tasks(connected, function, tasks, progress=progress, on_result=on_result)
    return [results[key] for key, _ in tasks]
