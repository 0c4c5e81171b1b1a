"""Run independent tasks (training runs, evaluation cells) in local processes or on Ray.

``run_tasks(fn, tasks)`` maps a picklable module-level ``fn`` over ``tasks``:
in the current process for one task, in a local process pool otherwise, or on
a Ray cluster when ``ray_address`` is given (``"local"`` starts a local Ray
instance; any other value is passed to ``ray.init(address=...)``). Ray is the
optional ``ray`` extra. Results come back in the order of ``tasks``.

Local workers end with the process that started them, however it ends
(``SIGTERM``, ``SIGKILL``, an exception): each watches its parent and exits
when the parent is gone, so a stopped study leaves no orphans computing on.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any


def run_tasks(fn: Callable[[Any], Any], tasks: list[Any], ray_address: str | None = None, max_workers: int | None = None,
              progress: str | None = None) -> list[Any]:  # fmt: skip
    """``[fn(t) for t in tasks]``, in parallel (see the module docstring); with ``progress`` (a label) a tqdm
    bar counts the local tasks as they finish (in any order; the results keep the order of ``tasks``)."""
    if ray_address is not None:
        return _run_ray(fn, tasks, ray_address)
    if len(tasks) <= 1:
        return [fn(t) for t in tasks]
    workers = max_workers or min(len(tasks), multiprocessing.cpu_count())
    context = multiprocessing.get_context("spawn")
    threads = max(1, multiprocessing.cpu_count() // workers)  # each worker's share of the cores
    with ProcessPoolExecutor(
        workers, mp_context=context, initializer=_worker_start, initargs=(os.getpid(), threads)
    ) as pool:
        futures = [pool.submit(fn, t) for t in tasks]
        bar = progress_bar(len(tasks), progress)
        for _ in as_completed(futures):
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
        return [f.result() for f in futures]


def progress_bar(total: int, label: str | None) -> Any:
    """A tqdm bar (the plots extra), or None without a label or without tqdm."""
    if label is None:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=label)


def _worker_start(parent: int, threads: int = 1) -> None:
    """Worker initializer: :func:`_exit_with_parent`; kernels compiled before they run (``MBS_ENVS_JIT=sync`` unless
    set otherwise): the pool keeps every core busy, where a process compiling beside each worker
    (:mod:`mbs_envs.dynamics.background`) would only share them; the planner's threads
    (:func:`controllers.planned_swingup.plan_threads`) limited to the worker's share of the cores, ``threads``."""
    os.environ.setdefault("MBS_ENVS_JIT", "sync")
    os.environ.setdefault("MBS_ENVS_PLAN_THREADS", str(threads))
    _exit_with_parent(parent)


def _exit_with_parent(parent: int, period: float = 0.5) -> None:
    """Worker initializer: a daemon thread ends this process once ``parent`` is no longer its parent."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(period)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="exit-with-parent").start()


def _run_ray(fn: Callable[[Any], Any], tasks: list[Any], address: str) -> list[Any]:
    try:
        import ray
    except ImportError:
        raise ValueError("--ray needs the ray extra: pip install -e '.[ray]'") from None
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(fn)
        return ray.get([remote.remote(t) for t in tasks])
    finally:
        if started:
            ray.shutdown()
