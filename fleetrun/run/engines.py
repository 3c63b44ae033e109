"""Where the simulation tasks run: in this process (``local``) or on a Dask cluster (``dask``).

Both engines run the same tasks on the same vehicle chunks and hand back the results keyed by
task, so the numbers cannot depend on the engine. Results stream back as tasks finish and only
a bounded number of tasks is in flight, so memory stays bounded however large the fleet.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator

from fleetrun.budget.result import EngineInfo
from fleetrun.errors import InputError

ENGINES = ("local", "dask")


class LocalEngine:
    name = "local"

    def __init__(self, **_):
        pass

    def run(self, function: Callable, tasks: Iterable) -> Iterator[tuple[int, object]]:
        for index, task in enumerate(tasks):
            yield index, function(task)

    def close(self):
        pass

    def describe(self) -> EngineInfo:
        return EngineInfo("local")


class DaskEngine:
    """Tasks on a Dask cluster: ``scheduler`` is an address, or None for a local cluster."""

    name = "dask"
    MAX_IN_FLIGHT_PER_WORKER = 4

    def __init__(self, scheduler: str | None = None, n_workers: int | None = None):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError("--engine dask needs Dask", hint='Install it: pip install "fleetrun[dask]" '
                             '(or pip install "dask[distributed]").') from None
        self.scheduler = scheduler
        self._cluster = None
        try:
            if scheduler:
                _check_reachable(scheduler)
                self.client = Client(scheduler, timeout="10s", set_as_default=False)
            else:
                import os

                workers = n_workers or max(1, min(4, (os.cpu_count() or 2)))
                self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                             processes=True, dashboard_address=None,
                                             silence_logs=40)
                self.client = Client(self._cluster, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            self.close()
            raise InputError(f"cannot reach the Dask scheduler at '{scheduler}' ({exc})",
                             hint="Check --scheduler (e.g. tcp://host:8786) and that the "
                                  "scheduler is running.") from None

    def run(self, function: Callable, tasks: Iterable) -> Iterator[tuple[int, object]]:
        from distributed import as_completed

        workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        limit = workers * self.MAX_IN_FLIGHT_PER_WORKER
        pending = iter(enumerate(tasks))
        index_of = {}

        def submit_next():
            item = next(pending, None)
            if item is None:
                return None
            index, task = item
            future = self.client.submit(function, task, pure=False)
            index_of[future.key] = index
            return future

        first = [f for f in (submit_next() for _ in range(limit)) if f is not None]
        if not first:
            return
        queue = as_completed(first, loop=self.client.loop)
        for future in queue:
            result = future.result()  # re-raises the task's exception here
            index = index_of.pop(future.key)
            future.release()
            following = submit_next()
            if following is not None:
                queue.add(following)
            yield index, result

    def close(self):
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        if self._cluster is not None:
            self._cluster.close()

    def describe(self) -> EngineInfo:
        return EngineInfo("dask", self.scheduler or "local cluster")


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast with OSError when nothing listens at a tcp address (distributed would retry
    until its timeout)."""
    import socket
    from urllib.parse import urlparse

    parts = urlparse(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls") or not parts.hostname or not parts.port:
        return  # other transports (inproc, ucx, ...): let distributed decide
    with socket.create_connection((parts.hostname, parts.port), timeout=timeout_s):
        pass


def make_engine(name: str, scheduler: str | None = None):
    if name == "local":
        if scheduler:
            raise InputError("--scheduler needs --engine dask")
        return LocalEngine()
    if name == "dask":
        return DaskEngine(scheduler)
    from fleetrun.errors import unknown_name_error

    raise unknown_name_error("engine", name, ENGINES)
