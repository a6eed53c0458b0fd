"""The Dask client: of a scheduler given by address, or of a LocalCluster started for a run;
and numba's kernels warmed before the tasks fan out.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from app.experiments.planning import Task
from app.experiments.spec import ExperimentError
from app.system.security import local_cluster_security
from app.system.signals import handling
from app.system.workers import default_workers


def warm_numba(tasks: list[Task], client: Any = None) -> None:
    """Compile (or load) numba's cached kernels once, in this process, before fanning out:
    several workers compiling the same cache at once can race (numba#4807). Then, given a Dask
    `client`, have every worker load them as it starts, not inside its first task."""
    from app.experiments.warm import WarmWorkers, controllers, warm_up

    configs = controllers([t.config for t in tasks])
    warm_up(configs)
    # After the cache is written: the workers only read it. Workers inside this process (an
    # in-process cluster) are warm already, and their warm-up would hold the event loop that
    # this process's scheduler and client share.
    if client is not None and not _in_process(client):
        client.register_plugin(WarmWorkers(configs))


def _in_process(client: Any) -> bool:
    """Every worker of `client`'s cluster lives in this process (`processes=False`)."""
    workers = client.scheduler_info().get("workers", {})
    return bool(workers) and all(str(a).startswith("inproc://") for a in workers)


NO_DASHBOARD: dict[str, Any] = {
    "dashboard_address": None,
    # The scheduler still serves its HTTP routes: on a free loopback port, not on 8787, which a
    # second cluster on the machine would find taken (and warn about).
    "scheduler_kwargs": {"dashboard_address": "127.0.0.1:0"},
}
"""LocalCluster arguments: no dashboard, and nothing on a fixed port."""


@contextmanager
def connect(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A Dask client: of the cluster at `scheduler`, or of a new LocalCluster on 127.0.0.1
    with `workers` single-threaded worker processes (default: one per core)."""
    import logging

    import dask
    from distributed import Client, LocalCluster

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        if scheduler:
            try:
                client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError) as error:
                raise ExperimentError(
                    f"cannot reach the Dask scheduler {scheduler}: {error}"
                ) from None
            try:
                yield client
            finally:
                client.close()
            return
        # Ctrl-C reaches the whole foreground process group: the worker processes started
        # meanwhile ignore it (they inherit that), and the client alone stops (closing its
        # cluster).
        with handling(signal.SIGINT, signal.SIG_IGN):
            cluster = LocalCluster(
                n_workers=workers or default_workers(),
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                silence_logs=logging.CRITICAL,  # a failed task is reported on one line
                security=local_cluster_security(),  # TLS: no other local user gets in
                **NO_DASHBOARD,
            )
        with cluster, Client(cluster) as client:
            yield client
