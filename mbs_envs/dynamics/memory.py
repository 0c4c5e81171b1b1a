"""Keep freed memory in the process: glibc's ``malloc`` otherwise returns it to the OS after every
batched step and takes it back, page fault by page fault, in the next.

A batched step allocates and frees its work arrays (the Runge-Kutta stages, the references, the
observations: megabytes at a few thousand members). glibc serves blocks above its *mmap
threshold* by ``mmap`` and unmaps them when freed, and trims the top of its heap when more than
its *trim threshold* lies free there. Both thresholds start low (128 kB) and adapt upward only
when an mmapped block is freed, so whether a step's memory is returned to the OS, and faulted in
again by the next step, depends on what the process allocated before. At a few thousand members
that cost hundreds of page faults per step and made the step several times slower per member;
with the thresholds below, none (figures in docs/performance.md).

:func:`keep_freed_memory` sets the two thresholds to the values glibc's own adaptation stops at
on 64-bit systems (``DEFAULT_MMAP_THRESHOLD_MAX`` = 32 MiB, and twice that for trimming). It is
process-wide and applied once, by the first vector env; the environment variable
``MBS_ENVS_KEEP_FREED_MEMORY=0`` leaves ``malloc`` as it is. Other C libraries (musl, macOS,
Windows) and allocators loaded instead of glibc's (jemalloc, tcmalloc) are left alone.
"""

from __future__ import annotations

import ctypes
import functools
import os
import platform
import sys
from collections.abc import Mapping

#: [bytes] blocks below this come from the heap, not from ``mmap`` (glibc's ceiling for its own threshold)
MMAP_THRESHOLD = 32 * 1024 * 1024
#: [bytes] free memory at the top of the heap kept up to this (twice the mmap threshold, as glibc's rule)
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD
#: glibc's ``mallopt`` parameters (malloc.h)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: set to "0" to leave malloc as it is
ENV_VAR = "MBS_ENVS_KEEP_FREED_MEMORY"


def wanted(environ: Mapping[str, str], platform_name: str, libc: str) -> bool:
    """Whether :func:`keep_freed_memory` changes anything: glibc on Linux, not switched off by :data:`ENV_VAR`."""
    return environ.get(ENV_VAR, "1").strip() != "0" and platform_name.startswith("linux") and libc == "glibc"


@functools.cache
def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds (module docstring), once per process.

    Returns
    -------
    bool
        Whether both were set (False where not :func:`wanted` or where ``mallopt`` refused).
    """
    if not wanted(os.environ, sys.platform, platform.libc_ver()[0]):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # pragma: no cover - glibc always has it
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1 and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
