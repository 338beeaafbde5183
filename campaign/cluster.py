"""Where a campaign runs: a local Dask cluster sized from this machine's cores and the CPU one run
needs, or any Dask cluster by its scheduler's address (started with the stock ``dask scheduler`` and
``dask worker`` commands). Each run asks for one unit of the worker resource ``swarm``; a local
worker offers one (one run at a time per worker), a worker of a cluster as many as its
``--resources swarm=N`` says."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import Any

RESOURCE = "swarm"


def local_workers(cpu_per_run: float, cores: int | None = None) -> int:
    """How many runs fly at once on this machine: its cores over what one run uses (at least one)."""
    cores = cores or len(os.sched_getaffinity(0))
    return max(1, int(cores // max(cpu_per_run, 1e-3)))


@contextlib.contextmanager
def connect(scheduler: str | None, workers: int | None, cpu_per_run: float) -> Iterator[Any]:
    """A dask.distributed Client: to ``scheduler`` (``tcp://HOST:8786``), or to a local cluster of
    ``workers`` single-threaded worker processes (default: local_workers)."""
    from distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler, timeout="30s") as client:
            yield client
        return
    n = workers or local_workers(cpu_per_run)
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            resources={RESOURCE: 1},
            dashboard_address=":0",
            silence_logs=50,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client
