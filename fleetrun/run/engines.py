"""Where the simulation tasks run: in this process (``local``) or on a Dask cluster (``dask``).

Both engines run the same tasks on the same vehicle chunks and hand back the results keyed by
task, so the numbers cannot depend on the engine. Results stream back as tasks finish and only
a bounded number of tasks is in flight, so memory stays bounded however large the fleet.
"""
from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterable, Iterator
from urllib.parse import urlparse

from fleetrun.budget.result import EngineInfo
from fleetrun.errors import InputError, unknown_name_error

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
    """Tasks on a Dask cluster: ``scheduler`` is an address, or None for a local cluster.

    A scheduler that cannot be used is an InputError within bounded time (docs/batch.md):
    an address that is not one, nothing or something else than a Dask scheduler listening
    (``CONNECT_TIMEOUT_S``), a scheduler without workers (``WORKERS_TIMEOUT_S``); both can be
    set with ``$FLEETRUN_DASK_TIMEOUT_S``.
    """

    name = "dask"
    MAX_IN_FLIGHT_PER_WORKER = 4
    CONNECT_TIMEOUT_S = 10.0
    WORKERS_TIMEOUT_S = 30.0

    def __init__(self, scheduler: str | None = None, n_workers: int | None = None):
        try:   # optional (the dask extra): imported only when --engine dask is asked for
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError("--engine dask needs Dask", hint='Install it: pip install "fleetrun[dask]" '
                             '(or pip install "dask[distributed]").') from None
        self.scheduler = scheduler
        self._cluster = None
        self.client = None
        if scheduler:
            self._connect(Client, scheduler)
        else:
            workers = n_workers or max(1, min(4, (os.cpu_count() or 2)))
            self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None, silence_logs=40)
            self.client = Client(self._cluster, set_as_default=False)

    def _connect(self, client_class, scheduler: str) -> None:
        connect_s, workers_s = _timeouts(self.CONNECT_TIMEOUT_S, self.WORKERS_TIMEOUT_S)
        address = _checked_address(scheduler)
        try:
            _check_reachable(address, connect_s)
            self.client = client_class(address, timeout=f"{connect_s}s", set_as_default=False)
        except Exception as exc:   # OSError, TimeoutError, a handshake a non-Dask server broke
            self.close()
            raise InputError(f"cannot reach the Dask scheduler at '{scheduler}' within {connect_s:g} s "
                             f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'no answer'})",
                             hint="Check --scheduler (e.g. tcp://host:8786) and that the "
                                  "scheduler is running.") from None
        try:
            self.client.wait_for_workers(1, timeout=workers_s)
        except Exception:
            self.close()
            raise InputError(f"the Dask scheduler at '{scheduler}' has no workers (none joined within "
                             f"{workers_s:g} s)", hint="Start workers: dask worker " + address) from None

    def run(self, function: Callable, tasks: Iterable) -> Iterator[tuple[int, object]]:
        from distributed import as_completed   # optional (the dask extra), as in __init__

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


def _timeouts(connect_s: float, workers_s: float) -> tuple[float, float]:
    """The connection and worker timeouts [s]; ``$FLEETRUN_DASK_TIMEOUT_S`` sets both."""
    text = os.environ.get("FLEETRUN_DASK_TIMEOUT_S")
    if not text:
        return connect_s, workers_s
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value < 1e6:
        raise InputError(f"$FLEETRUN_DASK_TIMEOUT_S '{text}' is not a positive number of seconds")
    return value, value


def _checked_address(scheduler: str) -> str:
    """``scheduler`` as a ``tcp://host:port`` (or ``tls://``, ``inproc://``, ...) address, or
    InputError naming what is wrong with it."""
    text = scheduler.strip()
    address = text if "://" in text else f"tcp://{text}"
    parts = urlparse(address)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme in ("tcp", "tls") and (not parts.hostname or port is None):
        raise InputError(f"'{scheduler}' is not a Dask scheduler address",
                         hint="Give --scheduler as tcp://host:port, e.g. tcp://10.0.0.5:8786")
    return address


MAX_DASK_FRAMES = 1 << 16     # a Dask message starts with its frame count (little-endian uint64)


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast with OSError (TimeoutError) unless a Dask scheduler answers at a tcp address:
    distributed would retry until its timeout when nothing listens, and wait without bound on
    a port where another server listens. A Dask scheduler writes its handshake as soon as it
    accepts (distributed.comm.core.connect reads it first), so anything else is found within
    ``timeout_s``."""
    parts = urlparse(address if "://" in address else f"tcp://{address}")
    if parts.scheme != "tcp" or not parts.hostname or not parts.port:
        return  # tls (the handshake comes after TLS), inproc, ucx, ...: let distributed decide
    with socket.create_connection((parts.hostname, parts.port), timeout=timeout_s) as probe:
        probe.settimeout(timeout_s)
        head = b""
        try:
            while len(head) < 8:
                chunk = probe.recv(8 - len(head))
                if not chunk:
                    raise ConnectionError("the server closed the connection: not a Dask scheduler")
                head += chunk
        except socket.timeout:
            raise TimeoutError("nothing answered: not a Dask scheduler") from None
    if not 0 < int.from_bytes(head, "little") <= MAX_DASK_FRAMES:
        raise ConnectionError("the server there does not speak Dask's protocol")


def make_engine(name: str, scheduler: str | None = None):
    if name == "local":
        if scheduler:
            raise InputError("--scheduler needs --engine dask")
        return LocalEngine()
    if name == "dask":
        return DaskEngine(scheduler)

    raise unknown_name_error("engine", name, ENGINES)
