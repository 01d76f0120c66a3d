"""The one pool that runs many independent tasks: in this process, in a local process pool,
or on Ray (``pip install "virtmech[cluster]"``). Results come back in the tasks' order.

    results = run_tasks(fn, items, workers=4)                 # processes
    results = run_tasks(fn, items, backend="ray")             # a local Ray, or a cluster's
    results = run_tasks(fn, items, workers=4, capture=True)   # a failed task's result is a
                                                              # TaskFailure, the rest go on

`fn` and the items must be picklable (a module-level function): the process pool's workers
start with forkserver (spawn where there is none), each forked from a server that has
imported `preload`, never with fork (the parent may hold threads).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from .errors import UserError

__all__ = ["BACKENDS", "CLUSTER_HINT", "TaskFailure", "process_context", "require_ray", "run_tasks"]

#: where the tasks go
BACKENDS = ("process", "ray")
CLUSTER_HINT = 'pip install "virtmech[cluster]"'


@dataclass(frozen=True)
class TaskFailure:
    """The result of a task that raised, or whose worker died (run_tasks(capture=True))."""

    error: str

    @staticmethod
    def of(e: BaseException) -> TaskFailure:
        return TaskFailure(f"{type(e).__name__}: {e}")


def require_ray():
    """The ray module, or a UserError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise UserError(
            f"--backend ray: Ray is not installed; install it with: {CLUSTER_HINT}"
        ) from None
    return ray


def process_context(preload: Sequence[str]):
    """The multiprocessing context of the process pool: forkserver where there is one
    (Linux, macOS), each worker forked from a server that has already imported `preload`;
    spawn elsewhere. Never fork: the parent may hold threads (tqdm's monitor, a host
    application's)."""
    import multiprocessing as mp

    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(preload))
        return ctx
    return mp.get_context("spawn")  # pragma: no cover


def run_tasks(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    workers: int | None = 1,
    backend: str = "process",
    address: str | None = None,
    capture: bool = False,
    isolate: bool = False,
    preload: Sequence[str] = (),
    on_done: Callable[[], None] | None = None,
) -> list[Any]:
    """[fn(item) for item in items], in the items' order. backend "process": in this
    process when workers <= 1 (or one item) unless `isolate` (then a pool of one: a task
    that crashes its process does not end the caller's), else in a pool of min(workers,
    items) processes (workers None: the machine's cores); "ray": Ray tasks (one CPU each, at most
    `workers` at once), on the Ray this process has initialised, else ray.init(address)
    (a local Ray when None), shut down again at the end. capture: a task that raises (or
    whose worker dies) gives a TaskFailure instead of raising. on_done() after each task."""
    if backend not in BACKENDS:
        raise UserError(f"--backend {backend!r}: expected one of {', '.join(BACKENDS)}")
    if backend == "ray":
        return _run_ray(fn, items, workers, address, capture, on_done)
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    if not isolate and (n <= 1 or len(items) <= 1):
        return [_call(fn, item, capture, on_done) for item in items]
    return _run_process(fn, items, max(1, min(n, len(items))), capture, preload, on_done)


def _call(fn, item, capture: bool, on_done):
    try:
        return fn(item)
    except Exception as e:
        if not capture:
            raise
        return TaskFailure.of(e)
    finally:
        if on_done is not None:
            on_done()


def _run_process(fn, items, workers: int, capture: bool, preload, on_done) -> list[Any]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = process_context(["virtmech.pool", *preload])
    results: list[Any] = [None] * len(items)
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = {pool.submit(fn, item): k for k, item in enumerate(items)}
        for f in as_completed(futures):
            k = futures[f]
            try:
                results[k] = f.result()
            except Exception as e:  # the task raised, or its worker died (e.g. killed)
                if not capture:
                    for other in futures:
                        other.cancel()
                    raise
                results[k] = TaskFailure.of(e)
            if on_done is not None:
                on_done()
    return results


def _ray_started(ray, address: str | None) -> bool:
    """Initialises Ray unless this process has; True if it did (and so shuts it down)."""
    if ray.is_initialized():
        return False
    import logging

    kw: dict[str, Any] = {"logging_level": logging.WARNING, "log_to_driver": False}
    try:
        if address:
            ray.init(address=address, **kw)
        else:
            ray.init(include_dashboard=False, **kw)
    except Exception as e:  # a cluster that cannot be reached: the user's to fix
        where = f"--address {address}" if address else "--backend ray"
        raise UserError(
            f"{where}: cannot start or connect to Ray ({type(e).__name__}: {e}); expected "
            "the address of a running Ray cluster (ray start --head prints it) or none "
            "for a local one"
        ) from None
    return True


def _run_ray(fn, items, workers: int | None, address: str | None, capture: bool, on_done):
    ray = require_ray()
    started = _ray_started(ray, address)
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(fn)
        results: list[Any] = [None] * len(items)
        limit = workers or len(items)
        pending: dict[Any, int] = {}  # at most `limit` tasks at once
        todo = iter(enumerate(items))
        for k, item in itertools.islice(todo, limit):
            pending[task.remote(item)] = k
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                k = pending.pop(ref)
                try:
                    results[k] = ray.get(ref)
                except Exception as e:  # the task or its worker failed
                    if not capture:
                        raise
                    results[k] = TaskFailure.of(e)
                if on_done is not None:
                    on_done()
                for k_next, item_next in itertools.islice(todo, 1):
                    pending[task.remote(item_next)] = k_next
        return results
    finally:
        if started:
            ray.shutdown()
