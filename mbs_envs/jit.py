"""The one numba configuration of every compiled kernel.

``error_model="numpy"``: a division by zero gives inf/NaN as in numpy (which
divergence detection then reports) instead of raising, and the compiled code
skips Python's zero-division checks.

Caching (``cache=True``) keeps compiled kernels in ``__pycache__`` between
processes. numba invalidates a cached function only when *its own* file changes,
not when a kernel it calls from another module does (numba issue #1833): after
editing, say, :mod:`mbs_envs.trig`, delete the ``*.nbi``/``*.nbc`` files
(``find mbs_envs -name '*.nb[ic]' -delete``) or stale code runs. A fresh install
has no cache.
"""

from __future__ import annotations

import numba


def njit(f=None, *, cache: bool = True, **options):
    """``numba.njit`` with the project's options; usable as ``@njit`` or ``@njit(cache=False)``.

    Generic kernels that take a model's kernels as arguments (``rk_run``,
    ``engine_step``, the constrained column loops) are ``cache=False``: their cache index would hold the
    argument kernels' types, which do not survive the process. They are cached
    inside the module-level bindings that call them (``advance_kernel``, a scene's
    ``step_kernel``); closures over kernels would compile again in every process.
    ``options`` go to ``numba.njit`` (e.g. ``inline="always"``).
    """
    decorate = numba.njit(cache=cache, error_model="numpy", **options)
    return decorate if f is None else decorate(f)
