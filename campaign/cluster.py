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

from bus.errors import ConfigError

RESOURCE = "swarm"
WORKERS_WAIT_S = 30.0


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
            check_slots(client, scheduler)
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


def check_slots(client: Any, scheduler: str, wait_s: float = WORKERS_WAIT_S) -> int:
    """How many runs the cluster at ``scheduler`` flies at once; a ConfigError naming the fix when no
    worker joins within ``wait_s`` or none offers the ``swarm`` resource (its tasks would wait for
    ever in Dask's ``no-worker`` state)."""
    try:
        client.wait_for_workers(1, timeout=wait_s)
    except TimeoutError:
        raise ConfigError(
            f"no Dask worker joined {scheduler} within {wait_s:.0f} s: start one with "
            f"`dask worker {scheduler} --resources {RESOURCE}=1`"
        ) from None
    workers = client.scheduler_info()["workers"].values()
    slots = sum(w.get("resources", {}).get(RESOURCE, 0) for w in workers)
    if slots < 1:
        raise ConfigError(
            f"no Dask worker at {scheduler} offers the `{RESOURCE}` resource ({len(workers)} joined), so no "
            f"run could start: restart each with `dask worker {scheduler} --resources {RESOURCE}=1` "
            "(one run at a time per unit; docs: campaigns)"
        )
    return int(slots)
