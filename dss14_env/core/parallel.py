"""Independent work items run one after another in-process or as Ray tasks, locally or on a
cluster.

The training seeds of a learned agent, the points of a hyperparameter sweep and the chunks of a
Monte-Carlo campaign are *embarrassingly parallel*: items that share nothing and return a small
JSON-ready result.  An executor maps a function over such items and hands the results back as
they finish, ``(index, result)``, so that the caller can write each one to disk at once (a
resumable run) and tick a progress bar:

* :class:`SerialExecutor` runs them one after another in this process;
* :class:`RayExecutor` runs each as a Ray task (``num_cpus`` per task, 1 by default) on a local
  Ray that it starts (``ray.init(num_cpus=n)``) or on a running cluster that it joins
  (``address="auto"`` on a cluster node, or ``"ray://head:10001"``).  Ray is an optional
  dependency, imported only here and only when a :class:`RayExecutor` is made; without it,
  :func:`require_ray` raises :class:`RayNotInstalledError` with the install command.

Both run every item inside :class:`pinned_threads`: BLAS and OpenMP thread pools (through
threadpoolctl) and torch's intra-op threads limited to ``threads`` (1 by default) for the item
and restored afterwards, and the Ray workers start with ``OMP_NUM_THREADS`` etc. set to the
same number, so that two tasks on two CPUs do not fight over them -- and so that an item
gives bit-for-bit the same result in-process and on Ray (a multi-threaded BLAS may sum in
another order).  A function whose result depends only on its item therefore returns the same
numbers with either executor.

>>> with SerialExecutor() as ex:
...     sorted(ex.map_unordered(abs, [-2, 3, -5]))
[(0, 2), (1, 3), (2, 5)]

A task that raises stops the run: the executor cancels what has not started and raises
:class:`TaskFailedError` naming the item (the results handed back before stay valid).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from dss14_env.core.counts import MAX_THREADS, check_count

#: the command that installs the optional Ray dependency (the ``ray`` extra of the package)
RAY_INSTALL = 'pip install -e ".[ray]"  (from a source checkout) or  pip install "dss14-env[ray]"'
#: environment variables that size the thread pools of BLAS, OpenMP and torch in a worker
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class RayNotInstalledError(RuntimeError):
    """Ray was asked for but is not installed; the message says how to install it."""


class TaskFailedError(RuntimeError):
    """One work item raised; the message names the item and the exception."""


def require_ray() -> Any:
    """Import and return the ``ray`` module.

    :raises RayNotInstalledError: if Ray is not installed (one line with the install command)
    """
    try:
        import ray
    except ImportError:
        raise RayNotInstalledError(f"Ray is not installed; install it with {RAY_INSTALL}") from None
    return ray


class pinned_threads:
    """Context manager: limit the thread pools of BLAS, OpenMP and torch to ``n``, restore on
    exit.

    numpy and scipy are loaded first so that both of their BLAS libraries are limited
    (threadpoolctl acts on the libraries loaded when it is entered).  torch's intra-op threads
    are set when torch is already imported, or always with ``torch=True`` (which imports it);
    torch imported later inside the block reads ``OMP_NUM_THREADS``, which the Ray workers get
    from :class:`RayExecutor`.

    :param n: threads per pool (>= 1)
    :param torch: ``True``: import torch and set its threads; ``None`` (default): set them if
        torch is already imported; ``False``: leave torch alone
    """

    def __init__(self, n: int = 1, torch: bool | None = None) -> None:
        self.n = check_count(n, "threads", 1, MAX_THREADS)
        self.torch = torch
        self._limiter: Any = None
        self._torch_threads: int | None = None

    def __enter__(self) -> pinned_threads:
        import numpy  # noqa: F401  (load both BLAS libraries before limiting them)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import threadpool_limits

        self._limiter = threadpool_limits(limits=self.n)
        if self.torch or (self.torch is None and "torch" in sys.modules):
            import torch

            self._torch_threads = torch.get_num_threads()
            torch.set_num_threads(self.n)
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._torch_threads is not None:
            sys.modules["torch"].set_num_threads(self._torch_threads)
            self._torch_threads = None
        if self._limiter is not None:
            self._limiter.restore_original_limits()
            self._limiter = None


def call_pinned(fn: Callable[[Any], Any], item: Any, threads: int = 1, torch: bool | None = None) -> Any:
    """``fn(item)`` inside :class:`pinned_threads` -- what every executor runs per item."""
    with pinned_threads(threads, torch):
        return fn(item)


class Executor(Protocol):
    """What the campaign and the multi-seed training need from an executor."""

    #: ``"serial"`` or ``"ray"``
    kind: str

    @property
    def n_workers(self) -> int:
        """Items that can run at the same time."""

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any],
                      labels: Sequence[str] | None = None) -> Iterator[tuple[int, Any]]:
        """``(index, fn(item))`` for every item, in the order they finish."""

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (kind, workers, address) for a results file."""

    def close(self) -> None:
        """Release what the executor started."""


def _label(labels: Sequence[str] | None, i: int) -> str:
    return labels[i] if labels is not None else f"item {i}"


class SerialExecutor:
    """Every item in this process, one after another, in order.

    :param threads: thread-pool size while an item runs (:class:`pinned_threads`)
    :param torch: torch's threads too (see :class:`pinned_threads`)
    """

    kind = "serial"

    def __init__(self, threads: int = 1, torch: bool | None = None) -> None:
        pinned_threads(threads)  # checks the value
        self.threads = threads
        self.torch = torch

    @property
    def n_workers(self) -> int:
        return 1

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any],
                      labels: Sequence[str] | None = None) -> Iterator[tuple[int, Any]]:
        """``(index, fn(item))`` in order; an exception becomes :class:`TaskFailedError`."""
        for i, item in enumerate(items):
            try:
                res = call_pinned(fn, item, self.threads, self.torch)
            except Exception as exc:  # noqa: BLE001 - re-raised with the item's name
                raise TaskFailedError(f"{_label(labels, i)} failed: {type(exc).__name__}: {exc}") from exc
            yield i, res

    def describe(self) -> dict[str, Any]:
        return {"kind": self.kind, "workers": 1, "threads_per_task": self.threads}

    def close(self) -> None:
        pass

    def __enter__(self) -> SerialExecutor:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def check_ray_options(address: str | None = None, num_cpus: int | None = None,
                      cpus_per_task: int = 1) -> None:
    """Check the options of a :class:`RayExecutor` without starting anything (the cluster they
    address, :func:`ray_target`, included).

    :raises ValueError: naming the bad option
    """
    if address is not None and (not isinstance(address, str) or not address.strip()):
        raise ValueError(f"--address: must be 'auto' or a Ray cluster address, got {address!r}")
    target = ray_target(address)
    if target.address is not None:
        split_address(target.address, target.named_by)
    if num_cpus is not None:
        check_count(num_cpus, "--num-cpus", 1, MAX_NUM_CPUS)
        if target.address is not None:
            raise ValueError(f"--num-cpus: sizes a local Ray; {target.named_by} names a cluster, "
                             f"which has its own CPUs")
    check_count(cpus_per_task, "cpus_per_task", 1, MAX_NUM_CPUS)


#: most seconds the running tasks of an interrupted run get to stop on their own (a training saves
#: its checkpoint at its next step; an evaluation in progress ends first)
STOP_GRACE_S = 60.0
#: seconds a cluster address has to answer before it is called unreachable
PROBE_TIMEOUT_S = 10.0
#: Ray's default ports: the cluster's GCS (``host:port``) and the client server (``ray://``)
RAY_PORT, RAY_CLIENT_PORT = 6379, 10001
#: most CPUs a local Ray may be given (``--num-cpus``)
MAX_NUM_CPUS = 4096
#: the environment variable that names the cluster ``ray.init`` joins when given no address or
#: ``"auto"``, and the file (in Ray's temporary folder) where ``ray start`` records the cluster
#: it started, which ``ray.init`` joins when given neither
RAY_ADDRESS_VAR, RAY_CLUSTER_FILE = "RAY_ADDRESS", "ray_current_cluster"


@dataclass(frozen=True)
class RayTarget:
    """The cluster a Ray started here joins, and what named it.

    :param address: the cluster's address (None: a new local Ray; ``"auto"``: Ray's own search)
    :param named_by: where the address comes from, for messages (``--address 10.0.0.1:6379``,
        ``RAY_ADDRESS=... (environment variable)``, the file ``ray start`` wrote)
    """

    address: str | None
    named_by: str

    def describe(self) -> str:
        """``Ray (local)``, or ``Ray at <address> (<what named it>)``."""
        if self.address is None:
            return "Ray (local)"
        return f"Ray at {self.address}" + ("" if self.named_by.startswith("--address") else
                                            f" (from {self.named_by})")


def _ray_temp_dir() -> Path:
    """Ray's temporary folder, as Ray finds it (``RAY_TMPDIR``, else ``TMPDIR``, else /tmp)."""
    root = os.environ.get("RAY_TMPDIR") or os.environ.get("TMPDIR") or "/tmp"
    return Path(root) / "ray"


def ray_target(address: str | None) -> RayTarget:
    """The cluster ``ray.init`` will join for ``address``, in Ray's own order: the
    ``RAY_ADDRESS`` environment variable when ``address`` is None or ``"auto"``; else
    ``address``; else (None or ``"auto"``) the cluster ``ray start`` recorded on this machine;
    else None (a local Ray) or ``"auto"``.
    """
    env = os.environ.get(RAY_ADDRESS_VAR, "").strip()
    asked = None if address is None else address.strip()
    if env and asked in (None, "auto"):
        return RayTarget(env, f"{RAY_ADDRESS_VAR}={env} (environment variable)")
    if asked not in (None, "auto"):
        return RayTarget(asked, f"--address {address}")
    file = _ray_temp_dir() / RAY_CLUSTER_FILE
    try:
        with file.open("rb") as fh:
            recorded = fh.read(1024).decode("utf-8", "replace").strip()
    except OSError:
        recorded = ""
    if recorded:
        return RayTarget(recorded, f"the cluster recorded in {file} by ray start ({recorded})")
    return RayTarget(asked, "--address auto" if asked else "")


def split_address(address: str, named_by: str = "--address") -> tuple[str, int] | None:
    """``(host, port)`` of a cluster address (``host``, ``host:port``, ``ray://host[:port]``),
    or None for ``"auto"`` (Ray finds the cluster itself).

    :param named_by: what named the address, for the message
    :raises ValueError: a port that is not a number in 1-65535
    """
    a = address.strip()
    if a == "auto":
        return None
    client = a.startswith("ray://")
    a = a.removeprefix("ray://").rstrip("/")
    host, sep, port = a.rpartition(":") if a.count(":") == 1 or a.startswith("[") else ("", "", "")
    if not sep:
        host, port = a, str(RAY_CLIENT_PORT if client else RAY_PORT)
    host = host.strip("[]")
    if not port.isdigit() or not 1 <= int(port) <= 65535 or not host:
        what = named_by.split(" ")[0].split("=")[0]
        raise ValueError(f"{what}: must be 'auto', host:port or ray://host:port, got {address!r}")
    return host, int(port)


def probe_address(address: str | None, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Check that something answers at the cluster a Ray started here would join
    (:func:`ray_target`: ``--address``, ``RAY_ADDRESS`` or the cluster ``ray start`` recorded)
    before Ray is asked to join it (Ray itself retries for many minutes and then may name
    another address).

    :raises RuntimeError: one line naming the address, what named it and why it cannot be reached
    """
    import socket

    target = ray_target(address)
    hp = None if target.address is None else split_address(target.address, target.named_by)
    if hp is None:
        return
    try:
        with socket.create_connection(hp, timeout=timeout):
            pass
    except OSError as exc:
        why = (f"no answer within {timeout:g} s" if isinstance(exc, TimeoutError)
               else (exc.strerror or str(exc)))
        raise RuntimeError(f"{target.named_by}: no Ray cluster can be reached at "
                           f"{hp[0]}:{hp[1]} ({why}); start one there (ray start --head), "
                           f"give its address (--address), or unset {RAY_ADDRESS_VAR} for a "
                           f"local Ray") from None


def ray_preflight(address: str | None = None, num_cpus: int | None = None) -> RayTarget:
    """Every check before Ray starts, whichever way the cluster is addressed: the options
    (:func:`check_ray_options`), Ray installed (:func:`require_ray`) and the cluster answering
    (:func:`probe_address`).

    :return: the cluster Ray will join (:func:`ray_target`)
    :raises ValueError, RayNotInstalledError, RuntimeError: one line each
    """
    check_ray_options(address, num_cpus)
    require_ray()
    probe_address(address)
    return ray_target(address)


class RayExecutor:
    """Every item as a Ray task, ``cpus_per_task`` CPUs each.

    A Ray that is already running in this process (``ray.is_initialized()``) is used as it is
    and left running; otherwise the executor starts one -- a local Ray with ``num_cpus`` CPUs
    (default: all of the machine's) when ``address`` is None, else it joins the cluster at
    ``address`` (``"auto"``: the cluster this machine belongs to) -- and shuts it down in
    :meth:`close`.  The workers import ``dss14_env`` from their own Python environment: on a
    local Ray that is this one; on a cluster the package must be installed on every node
    (``docs/scale.md``).

    :param address: None (local Ray), ``"auto"`` or a cluster address
    :param num_cpus: CPUs of the local Ray (only without ``address``)
    :param cpus_per_task: Ray's ``num_cpus`` of each task
    :param threads: thread-pool size inside each task (:class:`pinned_threads`), default
        ``cpus_per_task``
    :param torch: torch's threads too (see :class:`pinned_threads`)
    :raises RayNotInstalledError: without Ray
    :raises ValueError: on a bad option (named)
    """

    kind = "ray"

    def __init__(self, address: str | None = None, num_cpus: int | None = None, cpus_per_task: int = 1,
                 threads: int | None = None, torch: bool | None = None) -> None:
        check_ray_options(address, num_cpus, cpus_per_task)
        self.threads = cpus_per_task if threads is None else threads
        pinned_threads(self.threads)  # checks the value
        self.torch = torch
        self.cpus_per_task = cpus_per_task
        self.address = address
        ray = self._ray = require_ray()
        self._owned = not ray.is_initialized()
        if self._owned:
            probe_address(address)
            env = {"env_vars": {v: str(self.threads) for v in THREAD_ENV_VARS}}
            kwargs: dict[str, Any] = {"address": address} if address is not None else {"num_cpus": num_cpus}
            ray.init(include_dashboard=False, runtime_env=env, logging_level="WARNING", **kwargs)

    @property
    def n_workers(self) -> int:
        cpus = int(self._ray.cluster_resources().get("CPU", 1))
        return max(1, cpus // self.cpus_per_task)

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any],
                      labels: Sequence[str] | None = None) -> Iterator[tuple[int, Any]]:
        """Submit every item, then ``(index, result)`` as each task finishes.

        A failed task stops the others that have not finished (:meth:`stop`) and raises
        :class:`TaskFailedError`; so do closing the iterator early and an interruption (Ctrl-C,
        SIGTERM): no task is left running.
        """
        ray = self._ray
        remote = ray.remote(num_cpus=self.cpus_per_task, max_retries=0)(call_pinned)
        fn_ref = ray.put(fn)
        pending = {remote.remote(fn_ref, item, self.threads, self.torch): i for i, item in enumerate(items)}
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    i = pending.pop(ref)
                    try:
                        res = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:
                        cause = exc.cause if exc.cause is not None else exc
                        raise TaskFailedError(f"{_label(labels, i)} failed: {type(cause).__name__}: "
                                              f"{cause}") from None
                    yield i, res
        finally:
            self.stop(list(pending))

    def stop(self, refs: Sequence[Any], grace_s: float | None = None) -> None:
        """Stop the tasks ``refs``: first as Ctrl-C would (a KeyboardInterrupt in each, through
        its SIGINT handler: a training saves a checkpoint where it stops,
        :mod:`dss14_env.core.stop`), waiting up to ``grace_s`` (default :data:`STOP_GRACE_S`)
        for them to end, then by force.  A second interruption while waiting ends them at once.
        """
        if not refs:
            return
        ray = self._ray
        for ref in refs:
            ray.cancel(ref, force=False)
        try:
            ray.wait(list(refs), num_returns=len(refs),
                     timeout=STOP_GRACE_S if grace_s is None else grace_s)
        except KeyboardInterrupt:
            pass
        finally:
            for ref in refs:
                ray.cancel(ref, force=True)

    def describe(self) -> dict[str, Any]:
        res = self._ray.cluster_resources()
        return {"kind": self.kind, "address": self.address, "workers": self.n_workers,
                "cluster_cpus": float(res.get("CPU", 0.0)), "nodes": len(self._ray.nodes()),
                "cpus_per_task": self.cpus_per_task, "threads_per_task": self.threads,
                "ray_version": self._ray.__version__}

    def close(self) -> None:
        """Shut down the Ray this executor started (a Ray that was running is left alone)."""
        if self._owned and self._ray.is_initialized():
            self._ray.shutdown()
        self._owned = False

    def __enter__(self) -> RayExecutor:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def make_executor(ray: bool = False, address: str | None = None, num_cpus: int | None = None,
                  threads: int = 1, torch: bool | None = None) -> SerialExecutor | RayExecutor:
    """The executor the command-line options ask for.

    :param ray: Ray tasks (``--ray``) instead of the in-process loop
    :param address: a Ray cluster to join (``--address``; implies ``ray``)
    :param num_cpus: CPUs of a local Ray (``--num-cpus``; implies ``ray``)
    :param threads: thread-pool size per item
    :param torch: torch's threads too (see :class:`pinned_threads`)
    """
    if ray or address is not None or num_cpus is not None:
        return RayExecutor(address=address, num_cpus=num_cpus, cpus_per_task=threads, threads=threads,
                           torch=torch)
    return SerialExecutor(threads=threads, torch=torch)


__all__ = ["MAX_NUM_CPUS", "PROBE_TIMEOUT_S", "RAY_ADDRESS_VAR", "RAY_CLIENT_PORT", "RAY_CLUSTER_FILE",
           "RAY_INSTALL", "RAY_PORT", "STOP_GRACE_S", "Executor", "RayTarget",
           "RayExecutor", "RayNotInstalledError", "SerialExecutor", "ray_preflight", "ray_target",
           "TaskFailedError", "call_pinned", "check_ray_options", "make_executor", "pinned_threads",
           "probe_address", "require_ray", "split_address"]
