"""Tasks on Dask distributed: the one scale-out mechanism of `atr regress` and `atr eval`.

A LocalCluster of worker processes on this machine, or the scheduler of a cluster whose workers have this
checkout installed (`--scheduler tcp://HOST:8786`). Dask rather than a home-made pool: its scheduler already
does what both need at scale (one task per recording or flight, failures reported per task, a worker lost
mid-task retried on another, the same code on one machine or a cluster). It lives here, below both commands,
because the evaluation's library code (`atr.evaluation.experiment`) submits its flights itself.

How long to try a scheduler: Dask's own setting `distributed.comm.timeouts.connect` (30 s by default;
`DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s` in the environment changes it).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from atr.errors import ConfigError


class SchedulerError(ConfigError):
    """The Dask scheduler named by `--scheduler` did not answer."""


@contextmanager
def dask_client(scheduler: str | None, workers: int) -> Iterator[Any]:
    """A Dask client: of the scheduler at ``scheduler``, or of a LocalCluster started here; both are
    closed on leaving.

    Args:
        scheduler: address of a running scheduler (``tcp://HOST:8786``); None starts a LocalCluster.
        workers: the LocalCluster's worker processes, one task at a time each (ignored with a
            scheduler: the cluster's workers decide).

    Yields:
        A `distributed.Client`.

    Raises:
        SchedulerError: the scheduler did not answer within Dask's connect timeout.
        ConfigError: ``workers`` < 1.

    """
    from dask.distributed import Client, LocalCluster

    cluster = None
    if scheduler:
        try:
            client = Client(scheduler)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from exc
    else:
        if workers < 1:
            raise ConfigError(f"{workers} local Dask workers: must be >= 1")
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,  # one task per process: each task sizes its own thread pools
            processes=True,
            dashboard_address=":0",  # a free port: several clusters may run on one machine
            memory_limit=0,  # a worker's task may need most of the machine's memory (a replay, a scan)
            silence_logs=40,  # errors only: the commands print their own progress
        )
        client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def host_slots(client: Any) -> dict[str, int]:
    """Tasks that can run at once on each host of the cluster: the threads of its workers, added up.

    A task divides its host's cores by this (`task_slots`), so two worker processes on one machine do not
    each start a thread per core.
    """
    slots: dict[str, int] = {}
    for info in client.scheduler_info()["workers"].values():
        slots[info["host"]] = slots.get(info["host"], 0) + int(info["nthreads"])
    return slots


def task_slots(slots: Mapping[str, int]) -> int:
    """Inside a task: how many tasks its host runs at once (from `host_slots`; a worker that joined
    later counts its own threads).
    """
    from distributed import get_worker
    from distributed.comm import get_address_host

    worker = get_worker()
    return slots.get(get_address_host(worker.address), worker.state.nthreads)


def report(topic: str, message: Any) -> None:
    """Inside a task: send a small message to the client subscribed to ``topic`` (Dask's event log)."""
    from distributed import get_worker

    get_worker().log_event(topic, message)
